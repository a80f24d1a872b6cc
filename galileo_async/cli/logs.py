"""Where the CLI's logs go: -v on stderr (rich on a terminal, plain lines elsewhere), --log-file."""

from __future__ import annotations

import logging
import sys
import time
from pathlib import Path

__all__ = ["ALWAYS_SHOWN", "LOG_FORMAT", "setup_logging"]

#: One log line: UTC time (ISO 8601, milliseconds), level, logger, message; never wrapped.
LOG_FORMAT = "%(asctime)s.%(msecs)03dZ %(levelname)s %(name)s: %(message)s"
_DATE_FORMAT = "%Y-%m-%dT%H:%M:%S"
#: Loggers whose warnings stderr shows without -v: who asked this process, through its
#: control socket, to stop, cancel or pause the robot it drives.
ALWAYS_SHOWN = ("galileo_async.robot.control_server",)

_handlers: list[logging.Handler] = []
_shown: list[tuple[logging.Logger, logging.Handler]] = []


class _Stderr(logging.StreamHandler):  # type: ignore[type-arg]
    """Writes to sys.stderr as it is at each record (a live progress line redirects it)."""

    def __init__(self) -> None:
        logging.Handler.__init__(self, logging.WARNING)
        self.setFormatter(logging.Formatter("galileo: %(message)s"))

    @property
    def stream(self) -> object:
        return sys.stderr


def _plain(handler: logging.Handler) -> logging.Handler:
    formatter = logging.Formatter(LOG_FORMAT, _DATE_FORMAT)
    formatter.converter = time.gmtime
    handler.setFormatter(formatter)
    return handler


def setup_logging(verbose: int, log_file: Path | None = None) -> None:
    """-v: driver debug logs on stderr; -vv: raw frames too; ``log_file``: debug logs there.

    On a terminal stderr gets rich's columns; redirected, and in ``log_file``, one plain
    timestamped line per record, however long.
    """
    package = logging.getLogger("galileo_async")
    frames = logging.getLogger("galileo_async.transports.frames")
    while _handlers:  # an earlier invocation in this process (tests) set it up
        handler = _handlers.pop()
        package.removeHandler(handler)
        handler.close()
    while _shown:
        logger, handler = _shown.pop()
        logger.removeHandler(handler)
    package.setLevel(logging.NOTSET)
    frames.setLevel(logging.NOTSET)
    if not verbose:
        for name in ALWAYS_SHOWN:
            logger, shown = logging.getLogger(name), _Stderr()
            logger.addHandler(shown)
            _shown.append((logger, shown))
    if not verbose and log_file is None:
        return
    if verbose:
        if sys.stderr.isatty():
            from rich.console import Console
            from rich.logging import RichHandler

            console = Console(file=sys.stderr, highlight=False, soft_wrap=True)
            rich = RichHandler(console=console, show_path=False, rich_tracebacks=False)
            rich.setFormatter(logging.Formatter("%(name)s: %(message)s"))
            _handlers.append(rich)
        else:
            _handlers.append(_plain(logging.StreamHandler(sys.stderr)))
    if log_file is not None:
        file_handler = _plain(logging.FileHandler(log_file, encoding="utf-8"))
        file_handler.setLevel(logging.DEBUG)
        _handlers.append(file_handler)
    for handler in _handlers:
        package.addHandler(handler)
    package.setLevel(logging.DEBUG)
    frames.setLevel(logging.DEBUG if verbose >= 2 else logging.INFO)
