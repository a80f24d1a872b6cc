"""Usage errors of the option parser: one JSON object on stdout when the line has --json."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator, Sequence
from typing import Any, cast

import typer
from typer.core import TyperGroup

from .runner import ExitCode, out_console

__all__ = ["JSON_FLAG", "UsageErrorsAsJson", "json_requested"]

#: The option that asks for JSON output, globally or after a command name.
JSON_FLAG = "--json"
#: The parser's usage error (click's, or the copy of click that typer carries).
_USAGE_ERROR = cast(
    "type[Exception]",
    next(kind for kind in typer.BadParameter.__mro__ if kind.__name__ == "UsageError"),
)
#: A group called without arguments shows its help (exit 2): help, never an error object.
_HELP_NOT_ERROR = "NoArgsIsHelpError"
#: Where the root context keeps whether its command line had --json.
_META_KEY = "galileo_async.cli.json_requested"


def json_requested(args: Sequence[str]) -> bool:
    """True when ``--json`` is among ``args`` before a ``--`` that ends the options."""
    options = list(args)
    if "--" in options:
        options = options[: options.index("--")]
    return JSON_FLAG in options


@contextlib.contextmanager
def _as_json(wanted: bool) -> Iterator[None]:
    """With ``wanted``: a usage error prints ``{"error": "UsageError", …}`` and exits 2."""
    try:
        yield
    except _USAGE_ERROR as exc:
        if not wanted or type(exc).__name__ == _HELP_NOT_ERROR:
            raise
        message = cast("Any", exc).format_message()
        data = {"error": "UsageError", "message": message, "exit_code": int(ExitCode.USAGE)}
        out_console().print(json.dumps(data), markup=False)
        raise typer.Exit(int(ExitCode.USAGE)) from None


class UsageErrorsAsJson(TyperGroup):
    """The root group: a usage error of any command is JSON when the line has --json."""

    def make_context(
        self, info_name: str | None, args: list[str], parent: Any = None, **extra: Any
    ) -> Any:
        """The root context; a usage error in the global options is JSON with --json."""
        # Shell completion parses resiliently: its output stays as typer makes it.
        wanted = json_requested(args) and not extra.get("resilient_parsing", False)
        with _as_json(wanted):  # before parsing: the parser consumes ``args``
            ctx = super().make_context(info_name, args, parent, **extra)
        ctx.meta[_META_KEY] = wanted
        return ctx

    def invoke(self, ctx: Any) -> Any:
        """Run the command; its usage errors (and its subcommands') are JSON with --json."""
        with _as_json(bool(ctx.meta.get(_META_KEY, False))):
            return super().invoke(ctx)
