"""Option-parser errors with --json: one JSON object on stdout, exit 2; without it, click's text."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Sequence

import pytest

from galileo_async.cli.usage import json_requested

GALILEO = [sys.executable, "-m", "galileo_async"]
#: Bound on every run, seconds.
WAIT = 60


def galileo_runs(
    *commands: Sequence[str], env: dict[str, str] | None = None
) -> list[subprocess.CompletedProcess[str]]:
    """Run each ``galileo ARGS`` at once (neither stdout nor stderr a terminal); their results."""
    environment = {**os.environ, **(env or {})}
    environment.pop("GALILEO_PORT", None)
    environment.pop("GALILEO_ROBOT", None)
    started = [
        (
            list(args),
            subprocess.Popen(
                [*GALILEO, *args],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                env=environment,
            ),
        )
        for args in commands
    ]
    results = []
    for args, process in started:
        try:
            stdout, stderr = process.communicate(timeout=WAIT)
        finally:
            process.kill()
        results.append(subprocess.CompletedProcess(args, process.returncode, stdout, stderr))
    return results


#: (command line with --json, what click's message says). The same line without --json
#: must give click's text, whose ``Error:`` line carries the same message.
USAGE_ERRORS = [
    (["--json", "--bogus", "status"], "no such option --bogus"),
    (["--json", "--map-targets", "many", "status"], "Invalid value for '--map-targets'"),
    (["--json", "--layout", "v9", "status"], "'v9' is not one of"),
    (["--json", "--port", "sim://"], "Missing command."),
    (["--json", "nosuch"], "No such command 'nosuch'."),
    (["--json", "status", "--bogus"], "no such option --bogus"),
    (["status", "--bogus", "--json"], "no such option --bogus"),
    (["status", "--json", "--interval", "soon"], "Invalid value for '--interval'"),
    (["goto", "--json"], "Missing argument 'target_id'."),
    (["--json", "status", "--interval"], "Option '--interval' requires an argument."),
    (["--json", "nav", "bogus"], "No such command 'bogus'."),
]
IDS = [
    "global unknown option",
    "global option typed int",
    "global option checked by the callback",
    "no command",
    "unknown command",
    "--json before the command, unknown option after it",
    "--json after the command",
    "command option typed float, --json after the command",
    "missing argument, --json after the command",
    "option without its value",
    "unknown command of a group",
]


@pytest.mark.parametrize(("args", "says"), USAGE_ERRORS, ids=IDS)
def test_a_usage_error_is_one_json_object_with_json_and_clicks_text_without(
    args: list[str], says: str
) -> None:
    as_json, as_text = galileo_runs(args, [arg for arg in args if arg != "--json"])

    assert as_json.returncode == 2, as_json.stderr
    assert as_json.stderr == ""
    (line,) = as_json.stdout.splitlines()
    data = json.loads(line)
    assert set(data) == {"error", "message", "exit_code"}
    assert data["error"] == "UsageError"
    assert data["exit_code"] == 2
    assert says in data["message"]
    assert "Usage:" not in data["message"]
    assert "--help" not in data["message"]

    assert as_text.returncode == 2
    assert as_text.stdout == ""
    assert as_text.stderr.splitlines()[-1] == f"Error: {data['message']}"


def test_the_usage_banner_stays_in_the_text_form() -> None:
    (result,) = galileo_runs(["status", "--bogus"])
    assert result.returncode == 2
    assert result.stderr.splitlines()[:2] == [
        "Usage: galileo status [OPTIONS]",
        "Try 'galileo status --help' for help.",
    ]


def test_help_stays_help_with_json() -> None:
    asked, no_command = galileo_runs(["--json", "--help"], ["--json", "nav"])
    assert asked.returncode == 0, asked.stderr
    assert asked.stdout.startswith("Usage: galileo [OPTIONS] COMMAND [ARGS]...")
    assert "{" not in asked.stdout.splitlines()[0]
    # A group without its command shows its help (click's exit code 2), not an error object.
    assert no_command.returncode == 2
    assert no_command.stdout == ""
    assert no_command.stderr.startswith("Usage: galileo nav [OPTIONS] COMMAND [ARGS]...")
    assert "Commands:" in no_command.stderr


def test_shell_completion_ignores_json_and_usage_errors() -> None:
    def complete(words: str) -> dict[str, str]:
        return {
            "_GALILEO_COMPLETE": "complete_bash",
            "COMP_WORDS": words,
            "COMP_CWORD": str(len(words.split()) - 1),
        }

    commands, options = (
        galileo_runs([], env=complete(words))[0]
        for words in ("galileo --json --bogus st", "galileo --json goto x --t")
    )
    assert (commands.returncode, commands.stdout.split()) == (0, ["status", "stop"]), (
        commands.stderr
    )
    assert (options.returncode, options.stdout.split()) == (0, ["--timeout"]), options.stderr


def test_a_usage_error_after_a_command_that_ran_the_callback_is_json_too() -> None:
    # The global callback has run (Settings made) before the command's own options fail.
    (result,) = galileo_runs(["--json", "--port", "sim://", "goto", "-1x"])
    assert result.returncode == 2
    assert result.stderr == ""
    assert json.loads(result.stdout)["error"] == "UsageError"


@pytest.mark.parametrize(
    ("args", "wanted"),
    [
        (["--json", "status"], True),
        (["status", "--json"], True),
        (["status"], False),
        (["--jsonx"], False),
        (["send", "--", "--json"], False),
        (["--json", "send", "--", "x"], True),
    ],
)
def test_json_is_requested_by_the_flag_before_a_double_dash(args: list[str], wanted: bool) -> None:
    assert json_requested(args) is wanted
