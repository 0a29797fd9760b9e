"""Frozen dataclass configs and their command-line form.

Field docstrings are the documentation: ``add_config_args`` turns each field of a config class
into a ``--flag`` whose help is the field's docstring (CleanRL style), so ``--help`` and the code
never disagree. Components take their own config; no dict sub-configs.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import textwrap
import typing
from collections.abc import Mapping
from functools import cache
from typing import Any, TypeVar

from robogym_ray.errors import ConfigError

T = TypeVar("T")


@cache
def field_docs(cls: type) -> dict[str, str]:
    """{field name: docstring} read from the class source (the string after each field)."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        except (OSError, TypeError):  # no source (e.g. frozen app): help stays empty
            continue
        body = tree.body[0].body  # type: ignore[attr-defined]
        for node, nxt in zip(body, body[1:], strict=False):
            if (
                isinstance(node, ast.AnnAssign)
                and isinstance(node.target, ast.Name)
                and isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)
            ):
                docs[node.target.id] = " ".join(nxt.value.value.split())
    return docs


def _scalar_type(tp: Any) -> Any:
    """The element type of ``X | None`` / ``tuple[X, ...]``, or ``tp`` itself."""
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    return args[0] if args else tp


def add_config_args(
    parser: argparse.ArgumentParser, cls: type, prefix: str = "", only_given: bool = False
) -> None:
    """Add one ``--field-name`` option per field of the dataclass ``cls``.

    With ``only_given`` the parsed namespace holds only the flags given on the command line
    (so they can override a config file); ``--help`` still shows the dataclass defaults.
    """
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        tp = hints[f.name]
        flag = "--" + prefix + f.name.replace("_", "-")
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()  # type: ignore[misc]
        help_text = f"{docs.get(f.name, '')} (default: {default!r})"
        if only_given:
            default = argparse.SUPPRESS
        origin = typing.get_origin(tp)
        if tp is bool:
            parser.add_argument(
                flag,
                dest=f.name,
                action=argparse.BooleanOptionalAction,
                default=default,
                help=help_text,
            )
        elif origin is tuple or (
            origin is not None and typing.get_origin(_scalar_type(tp)) is tuple
        ):
            inner = _scalar_type(_scalar_type(tp))
            # "extend": a repeated flag adds to the list instead of replacing it.
            parser.add_argument(
                flag,
                dest=f.name,
                type=inner,
                nargs="+",
                action="extend",
                default=default if default is argparse.SUPPRESS else list(default),
                help=help_text,
            )
        else:
            parser.add_argument(
                flag, dest=f.name, type=_scalar_type(tp), default=default, help=help_text
            )


def config_from_args(cls: type[T], args: argparse.Namespace) -> T:
    """Build ``cls`` from the parsed options that ``add_config_args`` added."""
    values = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        if f.init and hasattr(args, f.name):
            value = getattr(args, f.name)
            values[f.name] = tuple(value) if isinstance(value, list) else value
    return cls(**values)


def merge_config(
    cls: type[T], values: Mapping[str, Any], source: str = "config", base: T | None = None
) -> T:
    """``cls(**values)`` (``base`` with ``values`` replaced, when given) with clear errors for
    unknown fields and bad values; JSON lists become tuples. The one place configs merge."""
    known = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(values) - known)
    if unknown:
        raise ConfigError(
            f"{source}: unknown {cls.__name__} field(s) {unknown}; known: {sorted(known)}"
        )
    try:
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**values) if base is None else dataclasses.replace(base, **values)  # type: ignore[type-var]
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{source}: invalid {cls.__name__}: {exc}") from None


def check_port(port: object, what: str) -> None:
    """ConfigError unless ``port`` is a TCP port number (0 = a free one). gRPC would not
    refuse one out of range: it binds ``port % 65536`` (``-1`` listens on 65535)."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ConfigError(f"{what} = {port!r}; expected a TCP port in [0, 65535] (0 = a free one)")
