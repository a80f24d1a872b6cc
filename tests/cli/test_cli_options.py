"""The command line's options: the help of those that take a robot's URL, and misspelt ones."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

from galileo_async.cli import ExitCode, app
from galileo_async.links import URL_SCHEMES, link_kind
from galileo_async.options import LINK_KINDS

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
    assert {kind for kind, _address in URL_SCHEMES.values()} == set(LINK_KINDS) - {"serial"}
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


def misspelt(option: str) -> str:
    """``option`` without its last letter but one: ``--timeout`` → ``--timeot``."""
    return option[:-2] + option[-1]


def option_typos() -> list[Any]:
    """(command line, misspelt option, meant option) for every long option of every command.

    The misspelt option goes before the command's arguments and after them (with a value
    when the option takes one: click must not take it for the command's argument).
    """
    cases = []
    for path in commands():
        command = command_at(path)
        ctx = command.make_context("galileo", [], resilient_parsing=True)
        params = command.get_params(ctx)
        arguments = ["3" for param in params if param.param_type_name == "argument"]
        if path == ():
            arguments = ["status"]  # the global options go before a command
        elif hasattr(command, "commands"):
            arguments = [sorted(command.commands)[0]]
        names = {name for param in params for name in (*param.opts, *param.secondary_opts)}
        for param in params:
            if param.param_type_name != "option":
                continue
            takes_value = not (param.is_flag or param.count)
            for meant in (*param.opts, *param.secondary_opts):
                typo = misspelt(meant)
                if not meant.startswith("--") or typo in names:
                    continue
                given = [typo, "5"] if takes_value else [typo]
                where = " ".join(["galileo", *path])
                cases.append(
                    pytest.param(
                        [*path, *given, *arguments], typo, meant, id=f"{where} {typo} before"
                    )
                )
                if path != ():
                    cases.append(
                        pytest.param(
                            [*path, *arguments, *given], typo, meant, id=f"{where} {typo} after"
                        )
                    )
    return cases


@pytest.mark.parametrize(("args", "typo", "meant"), option_typos())
def test_a_misspelt_option_is_named_with_the_one_meant(
    args: list[str], typo: str, meant: str
) -> None:
    result = CliRunner().invoke(app, args, env={"GALILEO_PORT": None, "COLUMNS": "200"})
    assert result.exit_code == ExitCode.USAGE, result.output
    error = result.output.strip().splitlines()[-1]
    assert error == f"Error: no such option {typo}; did you mean {meant}?", result.output


def test_every_command_has_its_options_checked() -> None:
    ids = {case.id for case in option_typos()}
    for command in ("goto", "goto-point", "rotate", "send", "status", "nav start", "fleet stop"):
        assert any(case_id.startswith(f"galileo {command} --") for case_id in ids), command
    assert "galileo goto --timeot after" in ids
    assert "galileo goto --timeot before" in ids


@pytest.mark.parametrize(
    "args",
    [
        ["goto", "-1"],
        ["goto-point", "-1.5", "-2", "--timeout", "5"],
        ["goto-point", "--timeout", "5", "-1.5", "-2"],
        ["rotate", "-90", "-t", "5"],
        ["send", "AddTarget", "-1.5", "-2e0", "--hex"],
    ],
    ids=["goto -1", "goto-point after", "goto-point before", "rotate", "send"],
)
def test_negative_numbers_are_still_arguments(args: list[str]) -> None:
    # No robot is needed: each line fails after parsing (range, --hex without a value,
    # …) or the parse is all that is checked: never "no such option -1".
    result = CliRunner().invoke(app, ["--port", "", *args], env={"GALILEO_PORT": None})
    assert "no such option" not in result.output.lower(), result.output


def test_json_usage_error_says_did_you_mean() -> None:
    result = CliRunner().invoke(app, ["--json", "goto", "3", "--timout", "5"])
    assert result.exit_code == ExitCode.USAGE
    message = json.loads(result.stdout)["message"]
    assert message == "no such option --timout; did you mean --timeout?"
