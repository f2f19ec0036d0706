"""Plugin commands (hook `register_commands`): a test plugin's command runs as `fusionkit <name>` under the
CLI's error handling, writes through the atomic output writer and is listed by `fusionkit plugins`; a
plugin may not take a built-in command's name; model outputs may not leave the output folder."""

from __future__ import annotations

import json

import pytest

from fusionkit.api import Command, ConfigError, PluginError, hookimpl, write_output_folder
from fusionkit.cli.main import COMMANDS, main
from fusionkit.components import BUILTIN_COMMANDS
from fusionkit.report.writer import MARKER, write_files


class Echo(Command):
    name = "test-echo"
    summary = "write a word into a file"

    def add_arguments(self, parser) -> None:
        parser.add_argument("word")
        parser.add_argument("--out", required=True)

    def run(self, args) -> int:
        if args.word == "bad":
            raise ConfigError("--word bad: expected a good word")
        write_output_folder(args.out, "test-echo", {"words/word.txt": args.word})
        return 0


class EchoPlugin:
    @hookimpl
    def register_commands(self):
        return [Echo]


class Run(Echo):
    name = "run"


class ClashingPlugin:
    @hookimpl
    def register_commands(self):
        return [Run]


def test_a_plugin_command_runs_as_a_subcommand_and_writes_through_the_output_writer(use_plugins, tmp_path, capsys):
    use_plugins(EchoPlugin())
    out = tmp_path / "out"
    assert main(["test-echo", "hello", "--out", str(out)]) == 0
    assert (out / "words" / "word.txt").read_text() == "hello"
    assert json.loads((out / MARKER).read_text())["entries"] == ["words"]
    assert main(["test-echo", "again", "--out", str(out)]) == 0  # its own earlier output may be replaced
    assert (out / "words" / "word.txt").read_text() == "again"


def test_a_plugin_commands_error_is_one_line_with_exit_2_and_debug_raises(use_plugins, tmp_path, capsys):
    use_plugins(EchoPlugin())
    assert main(["test-echo", "bad", "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err == "fusionkit: error: --word bad: expected a good word\n"
    with pytest.raises(ConfigError):
        main(["test-echo", "bad", "--out", str(tmp_path / "out"), "--debug"])
    assert not (tmp_path / "out").exists()


def test_plugins_lists_a_command_with_its_usage(use_plugins, capsys):
    use_plugins(EchoPlugin())
    assert main(["plugins"]) == 0
    assert "  command      test-echo                    write a word into a file" in capsys.readouterr().out
    assert main(["plugins", "test-echo"]) == 0
    assert capsys.readouterr().out.splitlines()[1] == "  usage: fusionkit test-echo --out OUT word"


class Percent(Echo):
    name = "test-percent"
    summary = "a 95 % interval"


class PercentPlugin:
    @hookimpl
    def register_commands(self):
        return [Percent]


def test_help_lists_a_command_whose_summary_holds_a_percent_sign(use_plugins, capsys):
    use_plugins(PercentPlugin())
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    assert "a 95 % interval" in capsys.readouterr().out


def test_a_plugin_may_not_take_a_builtin_command_name(use_plugins):
    assert tuple(COMMANDS) == BUILTIN_COMMANDS
    reg = use_plugins(ClashingPlugin())
    assert any("command 'run' is one of fusionkit's own commands" in reason for reason in reg.broken)
    assert reg.get("commands", "run") is None


@pytest.mark.parametrize("name", ["../escape.txt", "/tmp/absolute.txt", MARKER, "report.json"])
def test_output_files_stay_inside_the_folder_and_overwrite_nothing(tmp_path, name):
    (tmp_path / "report.json").write_text("{}")
    with pytest.raises(PluginError, match="robot model test"):
        write_files(tmp_path, {name: "x"}, "robot model test")
    assert not (tmp_path.parent / "escape.txt").exists()
