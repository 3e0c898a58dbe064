"""Hostile inputs (issue 16): paths from data stay inside their folder, names that become file names are checked."""

import pytest

from planefuse.io._paths import check_name, resolve_inside


@pytest.mark.parametrize("rel", ["../../../../etc/passwd", "/etc/passwd", "a/../../x", "C:\\x", ""])
def test_resolve_inside_refuses_paths_outside_the_recording(tmp_path, rel):
    with pytest.raises(ValueError, match="times_file"):
        resolve_inside(tmp_path, rel, "times_file")


def test_resolve_inside_refuses_a_symlink_pointing_out(tmp_path):
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "link").symlink_to(tmp_path)
    with pytest.raises(ValueError, match="outside"):
        resolve_inside(tmp_path / "rec", "link/x.csv", "file")


def test_resolve_inside_accepts_a_nested_path(tmp_path):
    assert resolve_inside(tmp_path, "cameras/cam0/times.csv", "f") == (tmp_path / "cameras/cam0/times.csv").resolve()


@pytest.mark.parametrize("name", ["x/../../somewhere", "a/b", "..", "", ".hidden", "a" * 65])
def test_camera_name_that_would_escape_the_output_folder_is_refused(name):
    with pytest.raises(ValueError, match="sensor name"):
        check_name(name, "sensor name")
