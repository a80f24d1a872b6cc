"""Usage errors of the option parser: a misspelt option named with the one meant, and
one JSON object on stdout when the line has --json."""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, cast

import typer
from typer.core import TyperCommand, TyperGroup

from .._checks import near_miss
from .runner import ExitCode, out_console

__all__ = [
    "JSON_FLAG",
    "NumberArguments",
    "UsageErrorsAsJson",
    "json_requested",
    "no_such_option",
]

#: The option that asks for JSON output, globally or after a command name.
JSON_FLAG = "--json"
#: The parser's usage error (click's, or the copy of click that typer carries).
_USAGE_ERROR = cast(
    "type[Exception]",
    next(kind for kind in typer.BadParameter.__mro__ if kind.__name__ == "UsageError"),
)
#: The parser's error for an unknown option, from the module of its usage error.
_NO_SUCH_OPTION = cast("type[Exception]", sys.modules[_USAGE_ERROR.__module__].NoSuchOption)
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


def no_such_option(name: str, options: Iterable[str]) -> str:
    """``no such option --timout; did you mean --timeout?`` (the near miss of ``options``)."""
    meant = near_miss(name, [option for option in options if option.startswith("--")])
    hint = f"; did you mean {meant}?" if meant is not None and name.startswith("--") else ""
    return f"no such option {name}{hint}"


def _option_names(ctx: Any) -> dict[str, int]:
    """The option names of ``ctx``'s command, each with how many words its value takes."""
    names: dict[str, int] = {}
    for param in ctx.command.get_params(ctx):
        if param.param_type_name == "option":
            takes = 0 if param.is_flag or param.count else param.nargs
            names.update(dict.fromkeys((*param.opts, *param.secondary_opts), takes))
    return names


def _reword(error: Exception) -> None:
    """Say an unknown option as no_such_option does, whoever raised it."""
    ctx = getattr(error, "ctx", None)
    if isinstance(error, _NO_SUCH_OPTION) and ctx is not None:
        error_any = cast("Any", error)
        error_any.message = no_such_option(error_any.option_name, _option_names(ctx))
        error_any.possibilities = None  # said in the message


def _is_number(word: str) -> bool:
    for parse in (float, lambda text: int(text, 0)):
        try:
            parse(word)
        except ValueError:
            continue
        return True
    return False


class NumberArguments(TyperCommand):
    """A command whose arguments may be negative numbers (``goto-point -1.5 2``).

    The parser would take ``-1.5`` for an option, so it is told to pass words it does not
    know on as arguments; then every other word that starts with ``-`` is checked here
    first: one that is no option of the command is "no such option", wherever it stands,
    and never an argument (``goto 3 --timout 5``: not "unexpected extra argument").
    """

    ignore_unknown_options = True

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        """Refuse an unknown option before the arguments are parsed, then parse."""
        names = _option_names(ctx)
        words = iter(args)
        for word in words:
            if word == "--":
                break
            if not word.startswith("-") or word == "-" or _is_number(word):
                continue
            name, equals, _value = word.partition("=")
            if name in names:
                for _ in range(0 if equals else names[name]):
                    next(words, None)  # the option's value, whatever it looks like
            elif word.startswith("--") or word[:2] not in names:  # -t5: -t and its value
                raise _NO_SUCH_OPTION(name, no_such_option(name, names), None, ctx)
        return super().parse_args(ctx, args)


@contextlib.contextmanager
def _as_json(wanted: bool) -> Iterator[None]:
    """With ``wanted``: a usage error prints ``{"error": "UsageError", …}`` and exits 2.

    An unknown option is said as no_such_option says it, with or without ``wanted``.
    """
    try:
        yield
    except _USAGE_ERROR as exc:
        _reword(exc)
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
