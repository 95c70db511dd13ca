"""Command-line options made from the config dataclasses: one source of truth.

A dataclass field becomes `--field-name`: its type from the annotation, its help text from
the docstring written under it, its default shown from the dataclass (argparse never holds
a default of its own), the values it takes listed where its metadata names them
(`choices`, e.g. `masspush.sim.pushers.pusher_field`), and its validation is the
dataclass's `__post_init__`. A command
adds the fields it takes (`add_fields`) and builds its config from what was given
(`build`): fields not given keep the dataclass's defaults.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import inspect
import textwrap
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from typing import Any

MISSING = dataclasses.MISSING


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """The docstring written under each field of a dataclass (PEP 257 attribute docstrings),
    whitespace collapsed."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        body = tree.body[0].body  # type: ignore[attr-defined]
        for node, following in zip(body, [*body[1:], None], strict=True):
            if (
                isinstance(node, ast.AnnAssign)
                and isinstance(node.target, ast.Name)
                and isinstance(following, ast.Expr)
                and isinstance(following.value, ast.Constant)
                and isinstance(following.value.value, str)
            ):
                docs[node.target.id] = " ".join(following.value.value.split())
    return docs


def _unwrap_optional(tp: Any) -> tuple[Any, bool]:
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return args[0], True
    return tp, False


def _default(f: dataclasses.Field) -> Any:
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return MISSING


def _comma_tuple(kind: type) -> Callable[[str], tuple]:
    def parse(text: str) -> tuple:
        try:
            return tuple(kind(part) for part in text.split(",") if part.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"wants a comma-separated list of {kind.__name__}, got {text!r}"
            ) from None

    parse.__name__ = f"comma-separated {kind.__name__}"
    return parse


def _show(value: Any) -> str:
    if isinstance(value, tuple):
        return ",".join(str(v) for v in value) if value else "none"
    return str(value)


def add_fields(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    cls: type,
    only: Iterable[str] | None = None,
    rename: Mapping[str, str] | None = None,
    required: Iterable[str] = (),
    prefix: str = "",
    pairs: Iterable[str] = (),
    help: Mapping[str, str] | None = None,
) -> None:
    """Add `--<field>` options for the fields of dataclass `cls` (`only` those, in that
    order). `rename` maps a field to another option name; `required` fields must be given;
    `prefix` names the namespace entries (for two dataclasses with a field of one name);
    `pairs` are tuple fields given as two numbers (`--mass-range 0.1 1`) rather than a
    comma-separated list; `help` replaces a field's docstring where the command reads the
    field differently."""
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    by_name = {f.name: f for f in dataclasses.fields(cls)}
    rename, required, pairs = dict(rename or {}), set(required), set(pairs)
    for name in only or by_name:
        f = by_name[name]
        tp, optional = _unwrap_optional(hints[name])
        default = _default(f)
        flag = "--" + rename.get(name, name).replace("_", "-")
        text = ((help or {}).get(name) or docs.get(name, "")).replace("%", "%%")
        if f.metadata.get("choices"):
            text += f" One of: {', '.join(f.metadata['choices'])}."
        kwargs: dict[str, Any] = {"dest": prefix + name, "default": argparse.SUPPRESS}
        if name in required or default is MISSING:
            # A field without a default is required: argparse says so in one line, where the
            # dataclass would raise a TypeError after parsing.
            kwargs["required"] = True
        elif default is not MISSING and not (tp is bool and default is False):
            text += f" (default: {_show(default)})" if default is not None else ""
        origin, args = typing.get_origin(tp), typing.get_args(tp)
        if tp is bool:
            # True or None (decided later) can be turned off: --no-<field>.
            on_off = default is not False
            kwargs["action"] = argparse.BooleanOptionalAction if on_off else "store_true"
        elif origin is tuple and name in pairs:
            kwargs.update(type=args[0], nargs=len(args), metavar=("LOW", "HIGH")[: len(args)])
        elif origin is tuple:
            kwargs.update(type=_comma_tuple(args[0]), metavar="A,B,...")
        elif origin is typing.Literal:
            kwargs["choices"] = args
        elif tp in (int, float, str):
            kwargs["type"] = tp
        else:
            raise TypeError(f"{cls.__name__}.{name}: no command-line form for {tp!r}")
        if optional and not text:
            text = "optional"
        parser.add_argument(flag, help=text, **kwargs)


def given(args: argparse.Namespace, cls: type, prefix: str = "") -> dict[str, Any]:
    """The fields of `cls` given on the command line."""
    out = {}
    for f in dataclasses.fields(cls):
        if hasattr(args, prefix + f.name):
            value = getattr(args, prefix + f.name)
            out[f.name] = tuple(value) if isinstance(value, list) else value
    return out


def build(
    cls: type, args: argparse.Namespace, base: Any = None, prefix: str = "", **extra: Any
) -> Any:
    """A `cls` from the command line: `base` (or `cls`'s defaults) with the given fields
    and `extra` replaced; the dataclass validates."""
    values = {**given(args, cls, prefix), **extra}
    if base is not None:
        return dataclasses.replace(base, **values)
    return cls(**values)


def add_bayes_option(p: argparse.ArgumentParser) -> None:
    """`--bayes KEY=VALUE` (repeatable): `BayesConfig` fields of a particle-filter model,
    read by `masspush.bayes.filter.bayes_overrides`."""
    p.add_argument(
        "--bayes", action="append", metavar="KEY=VALUE", default=None,
        help="change a BayesConfig field of a particle-filter arm (repeatable), "
        "e.g. --bayes likelihood_power=0.5; a range as LOW,HIGH: --bayes friction_range=0.3,1.2",
    )  # fmt: skip
