"""The registry of comparison methods: name -> :class:`~sparselt.methods.base.Method` instance."""

from __future__ import annotations

_METHODS = {}


def register(cls):
    """Class decorator: register one instance of a :class:`Method` subclass under ``cls.name``."""
    if not cls.name or cls.name in _METHODS:
        raise ValueError(f"method name {cls.name!r} is empty or already registered")
    _METHODS[cls.name] = cls()
    return cls


def method_names():
    """Registered method names, in registration order."""
    _load_builtin()
    return tuple(_METHODS)


def get_method(name):
    """The registered method called ``name``.

    Raises
    ------
    ValueError
        Unknown name; the message lists the registered methods.
    """
    _load_builtin()
    if name not in _METHODS:
        raise ValueError(f"unknown method {name!r}; registered methods: {', '.join(sorted(_METHODS))}")
    return _METHODS[name]


def _load_builtin():
    from . import path_tracing  # noqa: F401,I001  (they register, in this order)
    from . import samples_mean  # noqa: F401
    from . import cosamp_reconstruction  # noqa: F401
    from . import filtered  # noqa: F401
    from . import guided  # noqa: F401
    from . import sft_reconstruction  # noqa: F401
