"""docs/tutorial.md runs as written: its ``bash`` blocks, in order, on a short piece of the EPFL terrace (issue 38).

The only changes to the page's text: the data folder is the absolute path of ``../shared/data``, the frame list is
frames 1500-1545 (10 instants) instead of 1500-2995, and ``planefuse`` is this checkout's ``python -m planefuse``.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from conftest import shared_data

REPO = Path(__file__).resolve().parents[1]
TUTORIAL = REPO / "docs" / "tutorial.md"
#: The page's frame list and the test's shorter one.
FRAMES_TEXT, SHORT_FRAMES_TEXT = "range(1500, 3000, 5)", "range(1500, 1550, 5)"


def tutorial_commands() -> str:
    """The ``bash`` blocks of docs/tutorial.md, in order, as one script."""
    blocks = re.findall(r"```bash\n(.*?)```", TUTORIAL.read_text(encoding="utf-8"), flags=re.S)
    return "\n".join(blocks)


def test_the_tutorial_names_what_the_test_changes():
    text = tutorial_commands()
    assert text.count("DATA=../shared/data\n") == 1 and text.count(FRAMES_TEXT) == 1
    for command in ("planefuse import", "planefuse check", "planefuse config init", "planefuse run"):
        assert command in text, command


@pytest.mark.realdata
def test_tutorial_commands_run_as_written_on_a_piece_of_the_terrace(tmp_path):
    data = shared_data("epfl_video").parent
    shared_data("epfl_pom")
    script = (tutorial_commands().replace("DATA=../shared/data\n", f"DATA={data}\n")
              .replace(FRAMES_TEXT, SHORT_FRAMES_TEXT))
    prelude = f'set -euo pipefail\nplanefuse() {{ "{sys.executable}" -m planefuse "$@"; }}\n'
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")]),
               COLUMNS="200")
    res = subprocess.run(["bash", "-c", prelude + script], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=600)
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    # the configuration is config init's, for real video: the real-video profile on the imported area
    cfg = yaml.safe_load((tmp_path / "my-terrace" / "run.yaml").read_text())
    assert cfg["sensors"]["cameras"]["sensor_model"] == "generative"
    assert cfg["planes"]["x_range_m"] == [-0.5, 7.0] and cfg["planes"]["y_range_m"] == [-1.5, 9.5]
    assert "profile real-video" in " ".join(out.split())
    # check drew the ground on both cameras and the coverage map
    assert sorted(p.name for p in (tmp_path / "my-terrace" / "check").iterdir()) == \
        ["camera_c0.png", "camera_c1.png", "coverage.png"]
    # the run scored its 10 instants against the ground truth and wrote tracks
    run = tmp_path / "my-terrace" / "planefuse-out"
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["n_steps"] == 10 and metrics["n_camera_frames"] == 10
    assert (run / "tracks.csv").read_text().startswith("step,time_s,track_id")
