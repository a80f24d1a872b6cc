"""The command line's options: the help of those that take a robot's URL, and misspelt ones."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

from galileo_async.cli import ExitCode, app
from galileo_async.transports import URL_SCHEMES, link_kind
from galileo_async.transports.urls import LINK_SCHEMES

#: The click command of the ``galileo`` application.
ROOT: Any = typer.main.get_command(app)


def commands(command: Any = ROOT, path: tuple[str, ...] = ()) -> Iterator[tuple[str, ...]]:
    """The path (names after ``galileo``) of every command and group of the command tree."""
    yield path
    for name, child in sorted(getattr(command, "commands", {}).items()):
        yield from commands(child, (*path, name))


def command_at(path: tuple[str, ...]) -> Any:
    command = ROOT
    for name in path:
        command = command.commands[name]
    return command


def url_options() -> list[tuple[tuple[str, ...], Any]]:
    """(command path, option) of every option that takes a robot's URL (metavar URL)."""
    return [
        (path, param)
        for path in commands()
        for param in command_at(path).params
        if getattr(param, "metavar", None) == "URL"
    ]


def test_the_url_schemes_are_every_link_kind_with_a_scheme() -> None:
    assert {kind for kind, _address in URL_SCHEMES.values()} == set(LINK_SCHEMES)
    for scheme, (kind, _address) in URL_SCHEMES.items():
        assert link_kind(f"{scheme}://robot") == kind
    assert {"udp", "http", "https"} <= set(URL_SCHEMES)


def test_every_option_that_takes_a_url_names_every_scheme() -> None:
    found = url_options()
    assert ((), "--port") in [(path, option.opts[0]) for path, option in found]
    for path, option in found:
        for scheme in URL_SCHEMES:
            assert f"{scheme}://" in option.help, (path, option.opts, scheme)


def test_galileo_help_names_every_scheme() -> None:
    result = CliRunner().invoke(app, ["--help"], env={"COLUMNS": "100"})
    assert result.exit_code == 0
    for scheme in URL_SCHEMES:
        assert f"{scheme}://" in result.output, scheme


def test_an_empty_port_names_every_scheme() -> None:
    result = CliRunner().invoke(app, ["--port", "", "status"], env={"GALILEO_PORT": None})
    assert result.exit_code == ExitCode.USAGE
    for scheme in URL_SCHEMES:
        assert f"{scheme}://" in result.output, scheme


@pytest.mark.parametrize("scheme", ["frob", "htps"])
def test_an_unknown_scheme_lists_every_scheme(scheme: str) -> None:
    result = CliRunner().invoke(app, ["--port", f"{scheme}://robot", "status"])
    assert result.exit_code == ExitCode.USAGE, result.output
    for known in URL_SCHEMES:
        assert f"{known}://" in result.output, known
