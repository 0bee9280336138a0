"""The one digest of sparselt: SHA-256 of a value's canonical JSON.

Every identity and cache key (a scene's content identity, a cached
reference image's key, a procedural mesh's file name, an experiment's
identity, a scene setup) is hashed by :func:`digest`, so that two records
that are equal as JSON have the same digest, whatever the Python types that
built them (tuples or lists, NumPy or Python scalars), and every digest has
the same length (:data:`DIGEST_LENGTH` hexadecimal characters, all of
SHA-256's).

Byte strings (a file's content, a signal's data) are hashed by
:func:`bytes_digest`, the same hash without the JSON step.
"""

from __future__ import annotations

import hashlib
import json

#: Hexadecimal characters of every digest (all 256 bits of SHA-256).
DIGEST_LENGTH = 64


def _json_default(value):
    if hasattr(value, "tolist"):  # NumPy arrays and scalars
        return value.tolist()
    raise TypeError(f"cannot hash a {type(value).__name__} ({value!r}) as JSON: give numbers, text, lists or dicts")


def canonical(value):
    """``value`` as it reads back from JSON: tuples become lists, NumPy values Python ones, keys sorted.

    Raises
    ------
    TypeError
        A value JSON cannot hold (an object that is neither a number, text,
        list, dict nor a NumPy value).
    """
    return json.loads(canonical_text(value))


def canonical_text(value):
    """The canonical JSON text of ``value``: keys sorted, Python's default separators."""
    return json.dumps(value, sort_keys=True, default=_json_default)


def digest(value):
    """SHA-256 (hex, :data:`DIGEST_LENGTH` characters) of ``value``'s canonical JSON (:func:`canonical_text`).

    Parameters
    ----------
    value : JSON-able
        Numbers, text, booleans, None, lists, tuples, dicts with text keys,
        NumPy arrays and scalars.

    Returns
    -------
    str

    Raises
    ------
    TypeError
        A value JSON cannot hold.

    Examples
    --------
    >>> digest({"spp": 4, "shape": (2, 2)}) == digest({"shape": [2, 2], "spp": 4})
    True
    """
    return bytes_digest(canonical_text(value).encode("utf-8"))


def bytes_digest(*parts):
    """SHA-256 (hex, :data:`DIGEST_LENGTH` characters) of byte strings, concatenated."""
    hasher = hashlib.sha256()
    for part in parts:
        hasher.update(part)
    return hasher.hexdigest()


def file_digest(path):
    """SHA-256 (hex, :data:`DIGEST_LENGTH` characters) of a file's bytes, read in blocks."""
    hasher = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            hasher.update(block)
    return hasher.hexdigest()


__all__ = ["DIGEST_LENGTH", "bytes_digest", "canonical", "canonical_text", "digest", "file_digest"]
