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
import json
import math
import os
import re
import reprlib
import textwrap
import types
import typing
from collections.abc import Collection, Iterable, Mapping, Sequence
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

from robogym_ray.errors import ConfigError, FieldError
from robogym_ray.text import MAX_REASON_CHARS, clip_text, did_you_mean, preview
from robogym_ray.text import quote as quote_name

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


_STATES_DEFAULT = re.compile(r"\(default\b|\bdefault:", re.IGNORECASE)
"""A docstring that says "(default ..." or "default: ..." states its own default."""
_METAVARS = {int: "N", float: "X"}
"""Short metavars for numbers: ``--envs-per-worker N`` fits beside its help."""


def help_text(doc: str, default: object) -> str:
    """``doc`` and ``(default: VALUE)``, unless ``doc`` already says its default: as a user
    would type it (``navigation``, ``none``, a list spaced), ``%`` escaped for argparse."""
    if not _STATES_DEFAULT.search(doc):
        if isinstance(default, (tuple, list)):
            shown = " ".join(map(str, default)) or "none"
        else:
            shown = "none" if default is None else str(default) or "''"
        doc = f"{doc} (default: {shown})" if doc else f"(default: {shown})"
    return doc.replace("%", "%%")


def add_config_args(
    parser: argparse.ArgumentParser,
    cls: type,
    prefix: str = "",
    only_given: bool = False,
    *,
    groups: Mapping[str, Sequence[str]] | None = None,
    title: str | None = None,
) -> dict[str, Any]:
    """Add one ``--field-name`` option per field of the dataclass ``cls``.

    With ``only_given`` the parsed namespace holds only the flags given on the command line
    (so they can override a config file); ``--help`` still shows the dataclass defaults.

    Args:
        groups: ``{title: field names}``: ``--help`` sections, each listing its fields in this
            order. Every field of ``cls`` must be in exactly one and every name must be a
            field (ValueError when the parser is built: a new field cannot slip into no
            section, nor a renamed one stay behind).
        title: without ``groups``, one section for all the fields (none: the parser's own).

    Returns:
        The argument groups by title, for a command's own flags.
    """
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    if groups is None:
        groups = {title or "": tuple(fields)}
    else:
        listed = [name for names in groups.values() for name in names]
        unplaced = sorted(set(fields) - set(listed))
        unknown = sorted(set(listed) - set(fields))
        twice = sorted({name for name in listed if listed.count(name) > 1})
        if unplaced or unknown or twice:
            raise ValueError(f"{cls.__name__} help groups: fields in none {unplaced}, not fields "
                             f"{unknown}, in two {twice}")  # fmt: skip
    hints, docs = typing.get_type_hints(cls), field_docs(cls)
    sections: dict[str, Any] = {}
    for section, names in groups.items():
        target = sections[section] = parser.add_argument_group(section) if section else parser
        for name in names:
            f = fields[name]
            default = f.default if f.default is not dataclasses.MISSING else f.default_factory()  # type: ignore[misc]
            _add_flag(target, flag_name(name, prefix), name, hints[name],
                      argparse.SUPPRESS if only_given else default,
                      help_text(docs.get(name, ""), default))  # fmt: skip
    return sections


def flag_name(field: str, prefix: str = "") -> str:
    """The command-line flag of a config field: ``envs_per_worker`` -> ``--envs-per-worker``."""
    return "--" + prefix + field.replace("_", "-")


@dataclasses.dataclass(frozen=True)
class Words:
    """How the user gave a config's fields, so that an error names them as they were given:
    a command line's flags (``--run-name``, ``--resume``, ``--workers (8)``) or a Python
    call's keywords (``run_name=``, ``resume=True``, ``workers=8``)."""

    flags: bool

    def name(self, field: str) -> str:
        """``--run-name`` or ``run_name=``."""
        return flag_name(field) if self.flags else f"{field}="

    def label(self, field: str) -> str:
        """The setting before its value in a message: ``--storage /x`` or ``storage /x``."""
        return flag_name(field) if self.flags else field

    def setting(self, field: str, value: object) -> str:
        """What to pass for ``field`` to be ``value``: ``--resume`` / ``--seed 1``, or
        ``resume=True`` / ``seed=1``."""
        if not self.flags:
            return f"{field}={value!r}"
        return flag_name(field) if value is True else f"{flag_name(field)} {value}"

    def given(self, field: str, value: object) -> str:
        """A value the user gave, to change: ``--workers (8)`` or ``workers=8``."""
        return f"{flag_name(field)} ({value})" if self.flags else f"{field}={value!r}"


FLAGS, KEYWORDS = Words(flags=True), Words(flags=False)
"""The words of ``robogym-ray`` commands' errors, and of Python entries' (``robogym_ray.train``)."""


def _add_flag(target: Any, flag: str, dest: str, tp: Any, default: Any, help_: str) -> None:
    """One option of type ``tp``: a boolean ``--x/--no-x``, a list, or one value."""
    origin = typing.get_origin(tp)
    if tp is bool:
        target.add_argument(flag, dest=dest, action=argparse.BooleanOptionalAction,
                            default=default, help=help_)  # fmt: skip
    elif origin is tuple or (origin is not None and typing.get_origin(_scalar_type(tp)) is tuple):
        inner = _scalar_type(_scalar_type(tp))
        # "extend": a repeated flag adds to the list instead of replacing it.
        target.add_argument(
            flag,
            dest=dest,
            type=inner,
            nargs="+",
            action="extend",
            default=default if default is argparse.SUPPRESS else list(default),
            metavar=_METAVARS.get(inner),
            help=help_,
        )
    else:
        scalar = _scalar_type(tp)
        target.add_argument(flag, dest=dest, type=scalar, default=default,
                            metavar=_METAVARS.get(scalar), help=help_)  # fmt: skip


def config_from_args(cls: type[T], args: argparse.Namespace, prefix: str = "") -> T:
    """Build ``cls`` from the parsed options that ``add_config_args`` added (with ``prefix``);
    a bad value's error names its flag."""
    values = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        if f.init and hasattr(args, f.name):
            value = getattr(args, f.name)
            values[f.name] = tuple(value) if isinstance(value, list) else value
    flags = flags_of(values, prefix)
    # argparse converted each flag already; this catches what its converters let through (nan).
    check_fields(cls, values, cls.__name__, flags)
    try:
        return cls(**values)
    except FieldError as exc:
        raise _flagged(exc, flags) or exc from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(clip_text(str(exc), MAX_REASON_CHARS)) from None


def flags_of(fields: Iterable[str], prefix: str = "") -> dict[str, str]:
    """``{field: its flag}`` for ``fields`` given on a command line (``merge_config``'s
    ``flags``)."""
    return {name: flag_name(name, prefix) for name in fields}


def _flagged(exc: FieldError, flags: Mapping[str, str]) -> ConfigError | None:
    """``exc`` worded for the command line (``--workers 0: expected >= 1``) when its field came
    from a flag, else None."""
    flag = flags.get(exc.field)
    return ConfigError(f"{flag} {exc.shown}: expected {exc.expected}") if flag else None


def merge_config(
    cls: type[T],
    values: Mapping[str, Any],
    source: str = "config",
    base: T | None = None,
    flags: Mapping[str, str] | None = None,
) -> T:
    """``cls(**values)`` (``base`` with ``values`` replaced, when given) with clear errors for
    unknown fields and bad values; JSON lists become tuples. The one place configs merge.

    ``flags``: ``{field: flag}`` of the values given on the command line (``flags_of``): an
    error about one of them names the flag (``--workers 0: expected >= 1``), not the field.
    """
    flags = flags or {}
    check_fields(cls, values, f"{source}: {cls.__name__}", flags)
    try:
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**values) if base is None else dataclasses.replace(base, **values)  # type: ignore[type-var]
    except FieldError as exc:
        where = ConfigError(f"{source}: invalid {cls.__name__}: {exc}")
        raise _flagged(exc, flags) or where from None
    except (TypeError, ValueError) as exc:
        reason = clip_text(str(exc), MAX_REASON_CHARS)
        raise ConfigError(f"{source}: invalid {cls.__name__}: {reason}") from None


# -- checking input before anything starts ----------------------------------------------------
# One bounded repr for any value a user gave: a 50 MB string or a list nested 100000 deep is
# quoted by its start (reprlib stops at depth 3, so quoting never recurses deeply either).
_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxtuple, _REPR.maxdict = 3, 6, 6, 4
_REPR.maxstring = _REPR.maxother = 60
QUOTE_CHARS = 80
"""Characters of a user's value quoted in an error message."""


def quote(value: object) -> str:
    """``repr(value)`` cut to about QUOTE_CHARS characters, for one-line error messages."""
    if isinstance(value, str):
        return quote_name(value)
    text = _REPR.repr(value)
    return text if len(text) <= QUOTE_CHARS else text[:QUOTE_CHARS] + "..."


@cache
def _field_types(cls: type) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if f.init}


_NAMES = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}
_PLURALS = {bool: "booleans", int: "integers", float: "numbers", str: "strings"}


def _fits(tp: Any, value: object) -> bool:
    """Whether ``value`` (from JSON or a flag) is of the annotated type ``tp``."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return any(_fits(arg, value) for arg in args)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):  # a string is iterable, but not a list
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_fits(args[0], item) for item in value)
        return len(args) == len(value) and all(map(_fits, args, value))
    if tp is type(None):
        return value is None
    # bool is an int subclass to Python, never to a config: "workers": true is a mistake.
    if tp is bool or tp is str:
        return isinstance(value, tp)
    if tp is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if tp is float:
        return (
            isinstance(value, (int, float))
            and not isinstance(value, bool)
            and not math.isnan(value)
        )
    return True  # an annotation not checked here: the class's own __post_init__ decides


def _describe(tp: Any) -> str:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(arg) for arg in args)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_PLURALS.get(args[0], str(args[0]))}"
        return f"a list of {len(args)}: {', '.join(_describe(a) for a in args)}"
    if tp is type(None):
        return "null"
    if tp is float:
        return "a number (not NaN)"
    return _NAMES.get(tp, str(tp))


def check_keys(keys: Iterable[object], known: Collection[str], where: str, what: str) -> None:
    """ConfigError naming the ``keys`` that are not in ``known`` (``what``: e.g. ``field(s)``),
    with a "did you mean" for a single misspelt one, and the known ones."""
    unknown = [str(key) for key in keys if key not in known]
    if unknown:  # a hint only for a single unknown key: with several it could name either
        hint = did_you_mean(unknown[0], known) if len(unknown) == 1 else ""
        raise ConfigError(
            f"{where}: unknown {what} {preview(unknown)}{hint}; known: {', '.join(sorted(known))}"
        )


def check_fields(
    cls: type, values: Mapping[str, Any], where: str, flags: Mapping[str, str] | None = None
) -> None:
    """ConfigError naming the first key of ``values`` that is no field of the dataclass ``cls``
    or whose value is not of the field's annotated type (``where``: e.g. ``FILE: train``; a key
    in ``flags`` is named by its flag instead).

    Checked from the annotations, so every config class gets it, before its ``__post_init__``
    compares values (``"seed": "abc"`` would otherwise fail deep inside a worker)."""
    types_ = _field_types(cls)
    check_keys(values, types_, where, "field(s)")
    for key, value in values.items():
        if not _fits(types_[key], value):
            expected = _describe(types_[key])
            if flags and key in flags:
                raise ConfigError(f"{flags[key]} {quote(value)}: expected {expected}")
            raise ConfigError(f"{where}.{key} = {quote(value)}; expected {expected}")


def check_ranges(owner: str, checks: Iterable[tuple[bool, str, object, str]]) -> None:
    """FieldError for the first of ``checks`` that fails, each ``(ok, field, value, expected)``:
    ``Owner.field=VALUE; expected ...`` (a config class's ``__post_init__``)."""
    for ok, name, value, expected in checks:
        if not ok:
            shown = quote(value)
            raise FieldError(f"{owner}.{name}={shown}; expected {expected}", field=name,
                             shown=shown, expected=expected)  # fmt: skip


def read_json(path: str | os.PathLike, what: str = "config file") -> Any:
    """The JSON in ``path``, or a one-line ConfigError saying why not."""
    try:
        return json.loads(Path(path).read_text())
    except RecursionError:  # json's parser recurses once per nesting level
        raise ConfigError(f"cannot read {what} {path}: JSON nested too deeply") from None
    except (OSError, ValueError) as exc:  # ValueError: bad JSON, or bytes that are not UTF-8
        raise ConfigError(f"cannot read {what} {path}: {clip_text(str(exc), 200)}") from None


def check_dir_path(path: str | os.PathLike, what: str) -> None:
    """ConfigError when ``path`` cannot be (or become) a directory: it, or the nearest of its
    parents that exists, is something else. Checked before the work whose output goes there;
    ``mkdir`` would find it only afterwards and lose that work."""
    given = Path(path)
    for existing in (given, *given.parents):
        if existing.exists():
            if not existing.is_dir():
                raise ConfigError(f"{what} {quote_name(str(given))}: {existing} exists and is "
                                  "not a directory")  # fmt: skip
            return


def is_address(address: object) -> bool:
    """Whether ``address`` is ``HOST:PORT`` with a port in [1, 65535]."""
    host, sep, port = address.rpartition(":") if isinstance(address, str) else ("", "", "")
    return bool(sep and host and port.isdigit() and 0 < int(port) <= 65535)


def is_ray_address(address: object) -> bool:
    """Whether ``address`` is one ``ray.init`` joins: auto, HOST:PORT or ray://HOST:PORT
    (anything else fails only once Ray is asked, with a traceback)."""
    if address == "auto":
        return True
    return is_address(address.removeprefix("ray://") if isinstance(address, str) else address)


def check_address(address: object, what: str) -> None:
    """ConfigError unless ``address`` is ``HOST:PORT`` with a port in [1, 65535]."""
    if not is_address(address):
        raise ConfigError(f"{what} {quote(address)} is not HOST:PORT (port 1-65535)")


def check_port(port: object, what: str) -> None:
    """ConfigError unless ``port`` is a TCP port number (0 = a free one). gRPC would not
    refuse one out of range: it binds ``port % 65536`` (``-1`` listens on 65535)."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ConfigError(f"{what} = {port!r}; expected a TCP port in [0, 65535] (0 = a free one)")


def check_ray_address(address: object, what: str) -> None:
    """ConfigError unless ``address`` is one ``ray.init`` joins: auto, HOST:PORT or
    ray://HOST:PORT."""
    if not is_ray_address(address):
        raise ConfigError(
            f"{what} {quote(address)} is not auto, HOST:PORT or ray://HOST:PORT (port 1-65535)"
        )
