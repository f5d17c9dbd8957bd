"""Audit reports: one self-contained HTML file (+ Markdown) per run, and A-vs-B views."""

from sensorgap.report.build import write_report

__all__ = ["write_report"]
