"""The self-contained HTML report of a run."""

from ._html import library_versions, render_report, write_report

__all__ = ["library_versions", "render_report", "write_report"]
