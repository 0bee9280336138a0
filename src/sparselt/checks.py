"""Checks at the public boundary, shared by every module: TypeError for a wrong type, ValueError for a wrong value.

Each names the argument, the value given and what is allowed.
"""

from __future__ import annotations

import math
import numbers

import numpy as np


def check_integer(name, value, minimum, maximum=None):
    """``value`` as an int in ``[minimum, maximum]``.

    Raises
    ------
    TypeError
        Not an integer (bools and floats are refused, ``2.0`` included).
    ValueError
        Out of range.
    """
    if isinstance(value, bool) or not isinstance(value, (numbers.Integral, np.integer)):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    if value < minimum or (maximum is not None and value > maximum):
        allowed = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
        raise ValueError(f"{name} must be {allowed}, got {int(value)}")
    return int(value)


def check_positive_finite(value, name, *, hint="a positive finite number"):
    """``value`` as a float that is finite and > 0."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number ({hint}), got {value!r} of type {type(value).__name__}")
    value = float(value)
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"{name} must be finite and greater than 0 ({hint}), got {value!r}")
    return value


def finite_float_array(array, name, *, hint=""):
    """``array`` as a float64 ndarray, refusing what is not a finite real array.

    Parameters
    ----------
    array : array_like
    name : str
        The argument's name, for the message.
    hint : str, optional
        Appended to the message of a non-finite value (what to do about it).

    Raises
    ------
    ValueError
        Complex values, or NaN or infinite values (the message counts them).
    TypeError
        A value NumPy cannot read as numbers.
    """
    if np.iscomplexobj(array):
        raise ValueError(f"{name} must be real-valued; got an array of dtype {np.asarray(array).dtype}")
    try:
        converted = np.asarray(array, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise TypeError(f"{name} must be a numeric array; got {type(array).__name__} ({error})") from None
    if not np.all(np.isfinite(converted)):
        bad = int(np.count_nonzero(~np.isfinite(converted)))
        raise ValueError(f"{name} contains {bad} NaN or infinite value(s); only finite values are allowed" + hint)
    return converted
