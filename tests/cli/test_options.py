import argparse
from dataclasses import dataclass

import pytest

from masspush.cli import COMMANDS, build_parser, main
from masspush.cli.options import add_fields, build, field_docs
from masspush.evaluate import EvaluateConfig


@dataclass(frozen=True)
class Example:
    count: int = 3
    """How many, at most 100%."""
    pair: tuple[float, float] = (0.1, 1.0)
    """A low and a high."""
    names: tuple[str, ...] = ("a", "b")
    """Some names."""
    flag: bool = False
    """Say it."""
    maybe: str | None = None

    def __post_init__(self) -> None:
        if self.count < 1:
            raise ValueError(f"count must be >= 1, got {self.count}")


def parser_for(**kwargs) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser()
    add_fields(p, Example, **kwargs)
    return p


def test_field_docstrings_are_the_help_and_defaults_come_from_the_dataclass():
    assert field_docs(Example)["count"] == "How many, at most 100%."
    text = parser_for(pairs=("pair",)).format_help()
    assert "How many, at most 100%. (default: 3)" in text
    assert "(default: a,b)" in text


def test_only_given_fields_replace_the_defaults_and_the_dataclass_validates():
    p = parser_for(pairs=("pair",))
    config = build(Example, p.parse_args(["--pair", "0.5", "2", "--names", "x,y,z", "--flag"]))
    assert config == Example(pair=(0.5, 2.0), names=("x", "y", "z"), flag=True)
    assert build(Example, p.parse_args([])) == Example()
    with pytest.raises(ValueError, match="count must be >= 1"):
        build(Example, p.parse_args(["--count", "0"]))


def test_renamed_and_prefixed_fields():
    p = parser_for(only=("count",), rename={"count": "number"}, prefix="x_")
    args = p.parse_args(["--number", "7"])
    assert args.x_count == 7 and build(Example, args, prefix="x_").count == 7


def test_every_command_builds_its_options_from_its_dataclasses():
    parser = build_parser()  # every command's options: a field without a form would raise
    assert len(COMMANDS) >= 20
    help_text = parser.format_help()
    for group in ("estimate:", "data:", "train:", "real robot:", "report:"):
        assert group in help_text
    assert "bench physics" in help_text


def test_the_cli_shows_the_dataclass_default_and_refuses_what_it_refuses(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    shown = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert f"(default: {EvaluateConfig.__dataclass_fields__['episodes'].default})" in shown
    assert main(["evaluate", "--setting", "2link-1-10", "--model", "rp", "--episodes", "0"]) == 2
    assert "episodes must be an integer >= 1" in capsys.readouterr().err


def test_a_field_without_a_default_is_a_required_option(capsys):
    @dataclass(frozen=True)
    class Needs:
        setting: str
        """Which."""
        seed: int = 0

    p = argparse.ArgumentParser(prog="x")
    add_fields(p, Needs)
    assert build(Needs, p.parse_args(["--setting", "a"])) == Needs("a")
    with pytest.raises(SystemExit):
        p.parse_args(["--seed", "1"])  # argparse's one line, not a TypeError after parsing
    assert "the following arguments are required: --setting" in capsys.readouterr().err
    # The command it was found with: train-predictor without --setting.
    with pytest.raises(SystemExit) as exit_:
        main(["train-predictor", "--data", "somewhere"])
    assert exit_.value.code == 2
    assert "required: --setting" in capsys.readouterr().err


def test_a_pusher_option_lists_the_registry_in_its_help(capsys):
    from masspush.sim.pushers import PUSHERS

    with pytest.raises(SystemExit):
        main(["collect", "--help"])
    shown = " ".join(capsys.readouterr().out.split())
    assert "One of: " + ", ".join(PUSHERS) + "." in shown
    with pytest.raises(SystemExit):
        main(["bench", "arm", "--help"])
    shown = " ".join(capsys.readouterr().out.split())
    assert "One of: kuka," in shown and "stiff" not in shown.split("--arm ARM")[1].split("--")[0]
