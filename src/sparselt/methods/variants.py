"""Variants of a method: ``METHOD:NAME=VALUE[:NAME=VALUE...]``, one row of a comparison each.

``--methods pt,aaf-dof,aaf-dof:width_scale=0.5,cosamp:gamma=0.5`` compares
four estimators: ``aaf-dof`` with its options and with a half-width filter,
``cosamp`` at gamma 0.5. A row is named exactly as written (the results'
method column, cells and images). :func:`parse_method_variant` is the one
parser (the command line, ``compare`` and ``reproduce`` use it); file names
of a row come from :func:`variant_file_name`.

Options of a variant's row, lowest precedence first: each option's default,
``--option '*.NAME=VALUE'``, ``--option METHOD.NAME=VALUE`` (the method's
options, for every row of it), then the variant's own values.

Examples
--------
>>> parse_method_variant("cosamp:gamma=0.5")
('cosamp', {'gamma': '0.5'})
>>> variant_file_name("aaf-dof:width_scale=0.5")
'aaf-dof~3Awidth_scale~3D0.5'
"""

from __future__ import annotations

import re

#: Characters a row's file name keeps as they are (URL-unreserved, portable file names); every other one is
#: written ``~XX`` (its UTF-8 bytes in hexadecimal), ``~`` itself included: one name, one file, reversibly.
_KEPT = re.compile(r"[A-Za-z0-9._-]")


def parse_method_variant(text):
    """``(method name, {option: value text})`` of a method or a variant ``METHOD:NAME=VALUE[:NAME=VALUE...]``.

    Option names may use dashes for underscores; values are text, parsed
    and checked against the option's declaration (those whose range depends
    on the grid are checked when the options are resolved for a grid).

    Raises
    ------
    ValueError
        Empty text, a part that is not ``NAME=VALUE``, an unknown method (the
        message lists the registered ones), an option the method does not
        declare (it lists the method's options), an option given twice, or
        a value the option refuses (it names ``method.option`` and what is
        allowed).
    """
    from .registry import method_class

    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"a method is written METHOD or METHOD:NAME=VALUE[:NAME=VALUE...], got {text!r}")
    name, *parts = [part.strip() for part in text.strip().split(":")]
    cls = method_class(name)
    declared = {item.name: item for item in cls.Options.declared()}
    given = {}
    for part in parts:
        key, separator, value = part.partition("=")
        key = key.strip().replace("-", "_")
        if not separator or not key or not value.strip():
            raise ValueError(f"method variant {text!r}: {part!r} is not NAME=VALUE (a variant is written "
                             f"METHOD:NAME=VALUE[:NAME=VALUE...], e.g. cosamp:gamma=0.5)")
        if key not in declared:
            offered = ", ".join(declared) if declared else "none"
            raise ValueError(f"method variant {text!r}: method {name!r} has no option {key!r}; its options: "
                             f"{offered} ('sparselt methods {name}' describes them)")
        if key in given:
            raise ValueError(f"method variant {text!r} gives option {key!r} twice")
        item = declared[key]
        if item.derive is None and not callable(item.maximum):
            try:
                item.resolve(value.strip(), (), name)
            except (TypeError, ValueError) as error:
                raise ValueError(f"method variant {text!r}: {error}") from None
        given[key] = value.strip()
    return name, given


def is_variant(text):
    """Whether ``text`` is a variant (``METHOD:NAME=VALUE...``) rather than a plain method name."""
    return ":" in str(text)


def variant_file_name(text):
    """The file-name stem of a row: the text itself when it is a plain method name, else every character but
    letters, digits, ``.``, ``_`` and ``-`` written ``~XX`` (``cosamp:gamma=0.5`` -> ``cosamp~3Agamma~3D0.5``).

    Deterministic and one-to-one (a plain method name never holds ``~``), safe on every file system and in
    the report page's relative links.
    """
    return "".join(character if _KEPT.fullmatch(character) else
                   "".join(f"~{byte:02X}" for byte in character.encode("utf-8")) for character in str(text))


__all__ = ["is_variant", "parse_method_variant", "variant_file_name"]
