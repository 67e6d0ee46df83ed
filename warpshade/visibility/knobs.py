"""Method knobs declared once: a typed schema per visibility method.

Each method class lists its knobs in ``KNOBS`` (name, type, range or choices, help); the default of
each is the one of the constructor's keyword argument of the same name, read from its signature, so it
is written in one place. Everything else is derived from the schema (:class:`Knob`):

* the command-line flags (:func:`add_arguments`: ``--name`` with range and default in the help, argparse
  types that check the range and name the flag in errors; a boolean defaulting to True is ``--no-name``),
* the knobs picked out of parsed arguments (:func:`from_args`),
* validation and normalisation of knobs given in Python or a scene (:func:`normalise`: every knob
  filled in with its default, values coerced to the knob's type, unknown names and out-of-range
  values refused naming the knob), so equal configurations compare equal (the run's group key),
* what :meth:`~warpshade.visibility.base.VisibilityMethod.knobs` reports, and the check that every
  sweep entry is a valid knob set (:func:`check_sweep`).
"""

from __future__ import annotations

import argparse
import inspect
import math
from dataclasses import dataclass, replace
from typing import Any, Callable

MISSING = object()
"""A :class:`Knob` default not given: taken from the constructor's signature."""


def parse_vec3(text) -> tuple[float, float, float]:
    """``x,y,z`` (text, or a sequence of three numbers) -> tuple of three floats."""
    parts = [float(x) for x in (str(text).split(",") if isinstance(text, str) else text)]
    if len(parts) != 3:
        raise ValueError(f"expected x,y,z, got '{text}'")
    return tuple(parts)


@dataclass(frozen=True)
class Knob:
    """One knob of a visibility method.

    Attributes:
        name: Constructor keyword argument (the flag is ``--name`` with ``_`` as ``-``).
        type: ``int``, ``float``, ``str``, ``bool`` or ``"vec3"`` (three floats ``x,y,z``).
        help: One line for ``--help`` (the range and the default are appended); a boolean defaulting to
            True is offered as ``--no-name``, so its help says what that flag does.
        default: Default value; left out, the constructor's default for ``name``.
        minimum, maximum: Inclusive range of a number (None: unbounded).
        choices: Allowed values (None: any of the type).
        nullable: None is a valid value (e.g. "not set, decided from the mesh").
        cli: Offered on the command line (False: Python and scene files only).
        attr: Instance attribute holding the value as used, for ``knobs()`` (default: ``name``).
    """

    name: str
    type: Any
    help: str
    default: Any = MISSING
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple | None = None
    nullable: bool = False
    cli: bool = True
    attr: str | None = None

    @property
    def flag(self) -> str:
        """``--name`` with ``_`` as ``-``."""
        return "--" + self.name.replace("_", "-")

    @property
    def cli_flag(self) -> str:
        """The flag offered on the command line: :attr:`flag`, or ``--no-name`` for a boolean defaulting to True."""
        return f"--no-{self.flag[2:]}" if self.type is bool and self.default else self.flag

    def shown_default(self) -> str:
        """The default as written on the command line (``0,0,1`` for a vec3, ``none`` for None, ``on``/``off``)."""
        d = self.default
        if d is None:
            return "none"
        if self.type is bool:
            return "on" if d else "off"
        if self.type == "vec3":
            return ",".join(_num(x) for x in d)
        return str(d)

    def help_line(self) -> str:
        """The ``--help`` text of :attr:`cli_flag`: meaning, range (choices are in the flag's metavar), default."""
        if self.type is bool:
            return f"{self.help} (default: {self.name} {self.shown_default()})"
        rng = "" if self.choices is not None else self.describe_range()
        if rng and self.nullable:
            rng += " or unset"
        return f"{self.help}{'; ' + rng if rng else ''} (default {self.shown_default()})"

    def summary(self) -> str:
        """Compact form for a per-method list: ``--mask 32``; a boolean by its flag, ``--no-cull (cull on)``."""
        if self.type is bool:
            return f"{self.cli_flag} ({self.name} {self.shown_default()})"
        return f"{self.flag} {self.shown_default()}"

    def describe_range(self) -> str:
        """The constraint in words (``"an integer >= 1"``, ``"one of a, b"``), "" for none."""
        if self.choices is not None:
            return "one of " + ", ".join(str(c) for c in self.choices)
        what = {int: "an integer", float: "a number"}.get(self.type)
        if what is None:
            return ""
        if self.minimum is not None and self.maximum is not None:
            return f"{what} in {_num(self.minimum)}..{_num(self.maximum)}"
        if self.minimum is not None:
            return f"{what} >= {_num(self.minimum)}"
        if self.maximum is not None:
            return f"{what} <= {_num(self.maximum)}"
        return what

    def coerce(self, value):
        """``value`` as this knob's type, checked against its range and choices.

        Raises:
            ValueError: ``"<name> must be <constraint>, got <value>"``.
        """
        if value is None and self.nullable:
            return None
        try:
            v = self._convert(value)
        except (TypeError, ValueError):
            raise ValueError(f"{self.name} must be {self.describe_range() or _TYPE_WORDS.get(self.type, str(self.type))}"
                             f", got {value!r}") from None
        bad = ((self.choices is not None and v not in self.choices)
               or (self.minimum is not None and v < self.minimum)
               or (self.maximum is not None and v > self.maximum))
        if bad:
            raise ValueError(f"{self.name} must be {self.describe_range()}, got {v!r}")
        return v

    def _convert(self, value):
        import numpy as np

        if isinstance(value, np.generic):
            value = value.item()
        if self.type is bool:
            if isinstance(value, bool) or value in (0, 1):
                return bool(value)
            raise ValueError(value)
        if self.type is int:
            if isinstance(value, bool):
                raise ValueError(value)
            f = float(value)
            if not math.isfinite(f) or f != int(f):
                raise ValueError(value)
            return int(f)
        if self.type is float:
            if isinstance(value, bool):
                raise ValueError(value)
            f = float(value)
            if math.isnan(f):
                raise ValueError(value)
            return f
        if self.type is str:
            if not isinstance(value, str):
                raise ValueError(value)
            return value
        if self.type == "vec3":
            return parse_vec3(value)
        raise TypeError(f"knob {self.name}: unknown type {self.type!r}")

    def argparse_type(self) -> Callable[[str], Any]:
        """argparse ``type=``: text -> value, an :class:`argparse.ArgumentTypeError` argparse names the flag in."""

        def parse(text: str):
            if self.type in (int, float):
                try:
                    value = self.type(text)
                except ValueError:
                    raise argparse.ArgumentTypeError(f"invalid {self.type.__name__} value: {text!r}") from None
            else:
                value = text
            try:
                return self.coerce(value)
            except ValueError as exc:
                raise argparse.ArgumentTypeError(str(exc)[len(self.name) + 1:]) from None

        parse.__name__ = _TYPE_WORDS.get(self.type, "value")
        return parse


_TYPE_WORDS = {int: "int", float: "float", str: "str", bool: "bool", "vec3": "x,y,z"}


def _num(x) -> str:
    return str(int(x)) if float(x) == int(x) else repr(float(x))


def resolve_schema(cls, knobs) -> tuple[Knob, ...]:
    """``knobs`` with every missing default read from ``cls.__init__``'s signature.

    Raises:
        TypeError: a knob that is no keyword argument of the constructor, or has no default there.
    """
    params = inspect.signature(cls.__init__).parameters
    out = []
    for k in knobs:
        if k.default is MISSING:
            p = params.get(k.name)
            if p is None or p.default is inspect.Parameter.empty:
                raise TypeError(f"{cls.__name__}: knob {k.name!r} is not a constructor argument with a default")
            k = replace(k, default=p.default)
        if k.name not in params and not any(p.kind is p.VAR_KEYWORD for p in params.values()):
            raise TypeError(f"{cls.__name__}: knob {k.name!r} is not a constructor argument")
        out.append(k)
    return tuple(out)


def add_arguments(schema, parser: argparse.ArgumentParser) -> None:
    """Add the command-line knobs of ``schema`` to ``parser`` (or an argument group; ``dest`` is the knob's
    name), each with :meth:`Knob.help_line` as its help."""
    for k in schema:
        if not k.cli:
            continue
        text = k.help_line().replace("%", "%%")  # argparse formats help with %
        if k.type is bool:
            parser.add_argument(k.cli_flag, dest=k.name, action="store_false" if k.default else "store_true",
                                help=text)
            continue
        parser.add_argument(k.flag, dest=k.name, type=k.argparse_type(), default=k.default,
                            choices=k.choices, metavar=None if k.choices else k.name.upper(), help=text)


def cli_flags(schema) -> list[str]:
    """The command-line flags of ``schema``, in schema order."""
    return [k.cli_flag for k in schema if k.cli]


def summary(schema) -> str:
    """Every command-line knob of ``schema`` with its default, compactly (:meth:`Knob.summary`), comma-separated."""
    return ", ".join(k.summary() for k in schema if k.cli)


def from_args(schema, args: argparse.Namespace) -> dict:
    """The command-line knobs of ``schema`` out of arguments parsed with :func:`add_arguments`."""
    return {k.name: getattr(args, k.name) for k in schema if k.cli}


def defaults(schema) -> dict:
    """Every knob's default."""
    return {k.name: k.default for k in schema}


def normalise(schema, knobs: dict, method: str = "") -> dict:
    """Every knob of ``schema``, in schema order: ``knobs``' value coerced to the knob's type, else the default.

    Raises:
        ValueError: an unknown knob (the message lists the known ones) or a bad value, naming the knob
            (``"<knob> must be ..."``, prefixed with ``method: `` when given).
    """
    names = {k.name for k in schema}
    unknown = [n for n in knobs if n not in names]
    where = f"{method}: " if method else ""
    if unknown:
        raise ValueError(f"{where}unknown knob '{unknown[0]}' (its knobs: {', '.join(k.name for k in schema)})")
    out = {}
    for k in schema:
        if k.name in knobs:
            try:
                out[k.name] = k.coerce(knobs[k.name])
            except ValueError as exc:
                raise ValueError(f"{where}{exc}") from None
        else:
            out[k.name] = k.default
    return out


def changes(schema, knobs: dict) -> dict:
    """The knobs of a normalised set that differ from their defaults (how a configuration is shown)."""
    return {k.name: knobs[k.name] for k in schema if k.name in knobs and knobs[k.name] != k.default}


def check_sweep(schema, sweep: list[dict], method: str = "") -> None:
    """Refuse a sweep entry that is not a valid knob set (``order`` is allowed: the bench sweeps it too).

    Raises:
        ValueError: naming the entry and the knob.
    """
    for entry in sweep:
        normalise(schema, {k: v for k, v in entry.items() if k != "order"}, method)


__all__ = ["Knob", "add_arguments", "changes", "check_sweep", "cli_flags", "defaults", "from_args", "normalise",
           "parse_vec3", "resolve_schema", "summary"]
