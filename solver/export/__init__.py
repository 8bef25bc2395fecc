"""Outputs that leave the tool: text tables, reports, controller files."""

from .text import format_analysis

__all__ = ["format_analysis"]
