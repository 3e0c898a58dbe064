"""The tracker planefuse had before the Kalman tracker (nearest neighbour on the BOF velocity), loaded from git,
as a baseline in the same run. Nothing of it is copied into the repository: it is read from the commit
``PREVIOUS_TRACKER_COMMIT`` with ``git show`` and executed as a module of ``planefuse.tracking``.
"""

from __future__ import annotations

import subprocess
import sys
import types
from pathlib import Path

#: Last commit of main with the nearest-neighbour tracker (before issue 17's Kalman tracker).
PREVIOUS_TRACKER_COMMIT = "1dc1878"
_PATH = "src/planefuse/tracking/_tracker.py"


def previous_tracker_source(commit: str = PREVIOUS_TRACKER_COMMIT) -> str:
    """Source text of the previous ``planefuse/tracking/_tracker.py`` (needs a git checkout with history)."""
    root = Path(__file__).resolve().parents[1]
    try:
        return subprocess.run(["git", "show", f"{commit}:{_PATH}"], cwd=root, check=True, capture_output=True,
                              text=True).stdout
    except (OSError, subprocess.CalledProcessError) as exc:
        raise RuntimeError(f"previous tracker: cannot read {_PATH} at commit {commit} with git ({exc})") from None


def load_previous_tracker(source: str | None = None) -> types.ModuleType:
    """The previous tracker module (``MultiPersonTracker``, ``TrackerParams``) from its source text."""
    name = "planefuse.tracking._tracker_previous"
    if name in sys.modules and source is None:
        return sys.modules[name]
    module = types.ModuleType(name)
    module.__package__ = "planefuse.tracking"
    sys.modules[name] = module  # dataclasses look their module up
    exec(compile(source if source is not None else previous_tracker_source(), "_tracker_previous.py", "exec"),
         module.__dict__)
    return module
