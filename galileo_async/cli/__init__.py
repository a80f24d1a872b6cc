"""The ``galileo`` command line: drive, watch, record and simulate a Galileo robot."""

from __future__ import annotations

from .app import app, main
from .runner import ExitCode

__all__ = ["ExitCode", "app", "main"]
