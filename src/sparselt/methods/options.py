"""A method's options as data: declared once, validated in one place, received typed.

Every comparison method declares its options as a frozen dataclass derived
from :class:`MethodOptions`, one field per option made with :func:`option`:
its name (the field's), type (the annotation: ``bool``, ``int``, ``float`` or
``str``), default, allowed range or choices, help and thesis section. Options
several methods share are declared once, in a small dataclass the methods'
option classes inherit from (:class:`GuidingOptions` in
:mod:`sparselt.methods.guided`, say), so a shared option has one definition,
one default and one check.

The comparison resolves every method's options before anything runs
(:func:`resolve_options`): unknown names, wrong types and values out of range
are refused naming ``method.option``, the value and what is allowed; options
not given take their defaults, which may depend on the grid (``K = N / 200``);
the method then receives the typed, frozen options object as
``context.options``. The resolved values are what the comparison's identity,
``compare.json`` and every cell record hold (:meth:`MethodOptions.record`).

Examples
--------
>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class SmoothingOptions(MethodOptions):
...     radius: int = option(3, minimum=1, maximum=32, help="window radius in pixels", section="8.2")
>>> resolve_options(SmoothingOptions, {"radius": "5"}, grid_shape=(64, 64, 8, 8), owner="smooth").radius
5

References
----------
scikit-learn's ``_parameter_constraints`` (one declaration per parameter,
validated in one place); thesis 8.1.1 (the comparison's options).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import typing

import numpy as np

#: The types an option may have (what a command line can carry and JSON can store).
OPTION_TYPES = (bool, int, float, str)
_METADATA_KEY = "sparselt_option"
_TRUE = ("true", "yes", "on", "1")
_FALSE = ("false", "no", "off", "0")


@dataclasses.dataclass(frozen=True)
class Option:
    """One declared option of a method.

    Attributes
    ----------
    name : str
        The field name; on the command line ``--option METHOD.NAME=VALUE``
        (dashes and underscores are the same).
    type : {bool, int, float, str}
    default : object
        The default, or None when :attr:`derive` computes it from the grid.
    help : str
        One line: what the option does.
    section : str
        The thesis section or paper it comes from ('' when our own).
    minimum, maximum : float or None
        Allowed range (numbers); ``maximum`` may be a callable of the grid
        shape (a bound such as ``N / 2``), described by :attr:`maximum_text`.
    minimum_inclusive, maximum_inclusive : bool
        Whether the bounds themselves are allowed.
    choices : tuple of str (or int) or None
        Allowed values of a ``str`` (or ``int``) option.
    derive : callable or None
        ``derive(grid_shape)``: the default when it depends on the grid.
    default_text : str
        How a derived default reads ('N/200').
    maximum_text : str
        How a callable maximum reads ('N/2').
    """

    name: str
    type: type
    default: object
    help: str
    section: str = ""
    minimum: float | None = None
    maximum: object = None
    minimum_inclusive: bool = True
    maximum_inclusive: bool = True
    choices: tuple | None = None
    derive: object = None
    default_text: str = ""
    maximum_text: str = ""

    # ------------------------------------------------------------------ text
    def default_description(self):
        """The default as a user reads it: the value, or the rule that derives it."""
        if self.derive is not None:
            return self.default_text or "derived from the grid"
        return _text(self.default)

    def allowed(self):
        """What values are allowed, in words ('> 0', 'in [0, 1]', 'one of per-pixel, global', 'true or false')."""
        if self.type is bool:
            return "true or false"
        if self.choices is not None:
            return "one of " + ", ".join(_text(choice) for choice in self.choices)
        if self.type is str:
            return "any text"
        kind = "an integer" if self.type is int else "a finite number"
        maximum = self.maximum_text if callable(self.maximum) else (None if self.maximum is None else _text(self.maximum))
        if self.minimum is None and maximum is None:
            return kind
        if maximum is None:
            return f"{kind} {'>=' if self.minimum_inclusive else '>'} {_text(self.minimum)}"
        if self.minimum is None:
            return f"{kind} {'<=' if self.maximum_inclusive else '<'} {maximum}"
        left = "[" if self.minimum_inclusive else "("
        right = "]" if self.maximum_inclusive else ")"
        return f"{kind} in {left}{_text(self.minimum)}, {maximum}{right}"

    # ------------------------------------------------------------------ values
    def resolve(self, value, grid_shape, owner):
        """``value`` (or the default when ``value`` is :data:`dataclasses.MISSING`) checked and converted.

        Text (from a command line) is parsed to the option's type first.

        Raises
        ------
        ValueError
            Text that does not parse, a value out of range or not among the
            choices; the message names ``owner.name``, the value and what is
            allowed.
        TypeError
            A value of the wrong type (a float for an int option, a string
            for a number that is not text from a command line, ...).
        """
        if value is dataclasses.MISSING:
            value = self.derive(tuple(grid_shape)) if self.derive is not None else self.default
            if value is None:  # an optional option left unset
                return None
        label = f"option {owner}.{self.name}"
        if isinstance(value, str) and self.type is not str:
            value = self._parse(value, label)
        if self.type is bool:
            if not isinstance(value, (bool, np.bool_)):
                raise TypeError(f"{label} must be true or false, got {value!r}")
            return bool(value)
        if self.type is str:
            if not isinstance(value, str):
                raise TypeError(f"{label} must be text ({self.allowed()}), got {value!r}")
            if self.choices is not None and value not in self.choices:
                raise ValueError(f"{label} must be {self.allowed()}, got {value!r}")
            return value
        if self.type is int:
            if isinstance(value, bool) or not isinstance(value, (numbers.Integral, np.integer)):
                raise TypeError(f"{label} must be {self.allowed()}, got {value!r}")
            value = int(value)
        else:
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise TypeError(f"{label} must be {self.allowed()}, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ValueError(f"{label} must be {self.allowed()}, got {value!r}")
        if self.choices is not None and value not in self.choices:
            raise ValueError(f"{label} must be {self.allowed()}, got {_text(value)}")
        maximum = self.maximum(tuple(grid_shape)) if callable(self.maximum) else self.maximum
        low = self.minimum is not None and (value < self.minimum or (value == self.minimum and not self.minimum_inclusive))
        high = maximum is not None and (value > maximum or (value == maximum and not self.maximum_inclusive))
        if low or high:
            bound = f" (here {_text(maximum)})" if callable(self.maximum) else ""
            raise ValueError(f"{label} must be {self.allowed()}{bound}, got {_text(value)}")
        return value

    def _parse(self, text, label):
        stripped = text.strip()
        if self.type is bool:
            if stripped.lower() in _TRUE:
                return True
            if stripped.lower() in _FALSE:
                return False
            raise ValueError(f"{label} must be true or false, got {text!r}")
        try:
            return int(stripped) if self.type is int else float(stripped)
        except ValueError:
            raise ValueError(f"{label} must be {self.allowed()}, got {text!r}") from None


def option(default, *, help, section="", minimum=None, maximum=None, minimum_inclusive=True, maximum_inclusive=True,
           choices=None, derive=None, default_text="", maximum_text=""):
    """A dataclass field declaring one option of a method (see :class:`Option` for the arguments).

    Use it as the default of a field of a :class:`MethodOptions` dataclass;
    the field's name and annotation give the option's name and type.
    """
    if derive is not None and default is not None:
        raise ValueError("an option with a derived default declares default=None")
    if callable(maximum) and not maximum_text:
        raise ValueError("a callable maximum needs maximum_text (how the bound reads)")
    specification = dict(help=help, section=section, minimum=minimum, maximum=maximum,
                         minimum_inclusive=minimum_inclusive, maximum_inclusive=maximum_inclusive,
                         choices=tuple(choices) if choices is not None else None, derive=derive,
                         default_text=default_text, maximum_text=maximum_text)
    return dataclasses.field(default=default, metadata={_METADATA_KEY: specification})


@dataclasses.dataclass(frozen=True)
class MethodOptions:
    """Base of every method's options: a frozen dataclass whose fields are declared with :func:`option`.

    A method without options has this class itself (no fields).
    """

    @classmethod
    def declared(cls):
        """The :class:`Option` declarations, in field order."""
        return declared_options(cls)

    def record(self):
        """``{name: value}``, JSON-able: what identities, ``compare.json`` and cell records hold."""
        return {item.name: getattr(self, item.name) for item in dataclasses.fields(self)}

    def get(self, name, default=None):
        """The option ``name``, or ``default`` (for methods written when options were a dict)."""
        return getattr(self, name, default)


def declared_options(options_class):
    """The :class:`Option` declarations of an options dataclass.

    Raises
    ------
    TypeError
        Not a frozen dataclass derived from :class:`MethodOptions`, a field
        not made with :func:`option`, or a type outside :data:`OPTION_TYPES`.
    """
    if not (isinstance(options_class, type) and issubclass(options_class, MethodOptions)
            and dataclasses.is_dataclass(options_class) and options_class.__dataclass_params__.frozen):
        raise TypeError(f"{options_class!r} must be a frozen dataclass derived from sparselt.methods.MethodOptions")
    hints = typing.get_type_hints(options_class)
    declared = []
    for item in dataclasses.fields(options_class):
        specification = item.metadata.get(_METADATA_KEY)
        if specification is None:
            raise TypeError(f"{options_class.__name__}.{item.name} is not declared with sparselt.methods.option(...)")
        kind = _plain_type(hints.get(item.name))
        if kind not in OPTION_TYPES:
            raise TypeError(f"{options_class.__name__}.{item.name} has type {hints.get(item.name)!r}; options are "
                            f"{', '.join(t.__name__ for t in OPTION_TYPES)}")
        declared.append(Option(name=item.name, type=kind, default=item.default, **specification))
    return tuple(declared)


def _plain_type(hint):
    """``int`` from ``int`` or ``int | None``."""
    arguments = [argument for argument in typing.get_args(hint) if argument is not type(None)]
    return arguments[0] if typing.get_args(hint) and len(arguments) == 1 else hint


def resolve_options(options_class, given, *, grid_shape, owner):
    """The options object of one method: ``given`` values checked, every other option at its default.

    Parameters
    ----------
    options_class : type
        The method's :class:`MethodOptions` dataclass.
    given : mapping
        ``{option name: value}``; values may be text (from a command line)
        or typed; names may use dashes for underscores.
    grid_shape : tuple of int
        The comparison's signal grid (derived defaults and bounds).
    owner : str
        The method's name, for messages.

    Returns
    -------
    MethodOptions
        An instance of ``options_class``.

    Raises
    ------
    ValueError
        An option the method does not declare (the message lists those it
        does), or a value :meth:`Option.resolve` refuses.
    TypeError
        A value of the wrong type.
    """
    declared = {item.name: item for item in declared_options(options_class)}
    values = {}
    for name, value in dict(given).items():
        key = str(name).replace("-", "_")
        if key not in declared:
            offered = ", ".join(declared) if declared else "none"
            raise ValueError(f"method {owner!r} has no option {name!r}; its options: {offered} "
                             f"('sparselt methods {owner}' describes them)")
        values[key] = value
    return options_class(**{name: item.resolve(values.get(name, dataclasses.MISSING), grid_shape, owner)
                            for name, item in declared.items()})


def describe_options(options_class):
    """Rows ``(name, type, default, allowed, section, help)`` of text, for listings and help."""
    return [(item.name, item.type.__name__, item.default_description(), item.allowed(), item.section, item.help)
            for item in declared_options(options_class)]


def _text(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}" if math.isfinite(value) else str(value)
    return str(value)


__all__ = ["OPTION_TYPES", "MethodOptions", "Option", "declared_options", "describe_options", "option",
           "resolve_options"]
