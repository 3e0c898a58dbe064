"""The real-data guard of tests/conftest.py: unmarked readers fail, absence skips, or fails on CI."""

from __future__ import annotations

import pytest

import conftest
from conftest import shared_data


def test_an_unmarked_test_reading_shared_data_fails():
    with pytest.raises(pytest.fail.Exception, match="not marked @pytest.mark.realdata"):
        shared_data("epfl_pom")


@pytest.mark.realdata
def test_absent_data_skips_or_fails_when_required(tmp_path, monkeypatch):
    monkeypatch.setattr(conftest, "SHARED_DATA", tmp_path / "nowhere")
    monkeypatch.delenv(conftest.REQUIRE_ENV, raising=False)
    with pytest.raises(pytest.skip.Exception, match="is absent"):
        shared_data("epfl_pom")
    monkeypatch.setenv(conftest.REQUIRE_ENV, "1")
    with pytest.raises(pytest.fail.Exception, match="requires it"):
        shared_data("epfl_pom")
