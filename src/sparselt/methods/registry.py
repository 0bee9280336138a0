"""The registry of comparison methods: name -> :class:`~sparselt.methods.base.Method` class, built-ins and plug-ins.

:func:`get_method` makes an instance, the estimator with its resolved
options, from a name or a variant (``cosamp:gamma=0.5``,
:mod:`sparselt.methods.variants`); :func:`method_class` is the class itself.

Built-in methods register when :func:`method_names` or :func:`get_method` is
first called. Plug-ins add theirs in two ways, both through :func:`register`:

- an installed distribution's entry point in the group ``sparselt.methods``
  (``[project.entry-points."sparselt.methods"] mine = "my_package.methods"``):
  the module is imported, its decorated classes register;
- :func:`load_plugins` (``--plugin MODULE`` on ``compare``, ``methods`` and
  ``reproduce``): a module on the Python path.

Every class is checked against the contract when it registers
(:func:`check_method_class`); a name clash, a module that fails to import, or
a class that breaks the contract raises :class:`PluginError`, one line that
names the plug-in.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import inspect
import re

from ..rendering.layout import KINDS
from .options import declared_options

#: The entry-point group plug-in distributions declare their method modules in.
ENTRY_POINT_GROUP = "sparselt.methods"
#: A method name: lower case words joined by dashes (it names files and ``--option METHOD.NAME``).
NAME_PATTERN = re.compile(r"^[a-z0-9][a-z0-9-]*$")

_METHODS = {}
_SOURCES = {}
_LOADING = []  # the plug-in being imported, innermost last
_STATE = {"builtin": False, "entry_points": False}


class PluginError(ValueError):
    """A plug-in that cannot be used: its module fails to import, a name clash, or a broken contract."""


def _source(cls):
    return _LOADING[-1] if _LOADING else cls.__module__


def check_method_class(cls, source=None):
    """Refuse a method class that breaks the contract of :class:`~sparselt.methods.base.Method`.

    Checked: a subclass of ``Method``; ``name`` matching :data:`NAME_PATTERN`;
    ``kinds`` a non-empty tuple of signal kinds; ``run(self, context,
    budget, timer)`` implemented with exactly that signature; ``requires`` a
    tuple of :class:`~sparselt.methods.preconditions.Requirement`;
    ``Options`` a frozen :class:`MethodOptions` dataclass whose defaults are
    valid; ``baseline`` and ``thesis_procedure`` booleans; ``family`` text.

    Raises
    ------
    PluginError
        One line naming ``source`` (the plug-in) and what is wrong.
    """
    from .base import Method
    from .preconditions import Requirement

    where = f"plug-in {source or getattr(cls, '__module__', '?')!r}"
    label = getattr(cls, "__qualname__", repr(cls))
    if not (isinstance(cls, type) and issubclass(cls, Method)):
        raise PluginError(f"{where}: {label} is not a subclass of sparselt.methods.Method")
    name = cls.name
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise PluginError(f"{where}: {label}.name must be lower-case words joined by dashes (it names files and "
                          f"--option METHOD.NAME), got {name!r}")
    kinds = cls.kinds
    if isinstance(kinds, str) or not isinstance(kinds, (tuple, list)) or not kinds or any(
            kind not in KINDS for kind in kinds):
        raise PluginError(f"{where}: method {name!r} declares kinds {kinds!r}; kinds must be a non-empty tuple of "
                          f"{', '.join(KINDS)}")
    if cls.run is Method.run or not callable(cls.run):
        raise PluginError(f"{where}: method {name!r} does not implement run(context, budget, timer)")
    try:
        parameters = list(inspect.signature(cls.run).parameters)
    except (TypeError, ValueError):
        parameters = None
    if parameters is not None and parameters[1:] != ["context", "budget", "timer"]:
        raise PluginError(f"{where}: method {name!r} defines run({', '.join(parameters)}); the signature is "
                          "run(self, context, budget, timer): time every phase in the PhaseTimer the harness passes "
                          "(with timer('sampling'): ...) and return MethodResult(image=..., path_samples=..., "
                          "details=...) without seconds")
    if not isinstance(cls.requires, tuple) or not all(isinstance(item, Requirement) for item in cls.requires):
        raise PluginError(f"{where}: method {name!r}: requires must be a tuple of "
                          f"sparselt.methods.preconditions.Requirement, got {cls.requires!r}")
    try:
        declared = declared_options(cls.Options)
    except TypeError as error:
        raise PluginError(f"{where}: method {name!r}: {error}") from None
    for item in declared:
        if item.derive is None and not callable(item.maximum):
            try:
                item.resolve(item.default, (), name)
            except (TypeError, ValueError) as error:
                raise PluginError(f"{where}: method {name!r}: the default of {item.name!r} is refused: "
                                  f"{error}") from None
    for attribute in ("baseline", "thesis_procedure", "needs_resolution_multiple"):
        if not isinstance(getattr(cls, attribute), bool):
            raise PluginError(f"{where}: method {name!r}: {attribute} must be True or False, got "
                              f"{getattr(cls, attribute)!r}")
    if not isinstance(cls.family, str) or not cls.family:
        raise PluginError(f"{where}: method {name!r}: family must be a word such as 'filter', got {cls.family!r}")
    if not isinstance(cls.description, str):
        raise PluginError(f"{where}: method {name!r}: description must be text")


def register(cls):
    """Class decorator: check ``cls`` against the contract and register it under ``cls.name``.

    Raises
    ------
    PluginError
        The contract is broken (:func:`check_method_class`), the name is
        taken (the message names both sources), or a second baseline.
    """
    source = _source(cls)
    check_method_class(cls, source)
    if cls.name in _METHODS:
        raise PluginError(f"plug-in {source!r}: method name {cls.name!r} is already registered by "
                          f"{_SOURCES[cls.name]!r}; choose another name")
    if cls.baseline:
        other = [name for name, registered in _METHODS.items() if registered.baseline]
        if other:
            raise PluginError(f"plug-in {source!r}: method {cls.name!r} declares baseline = True, but {other[0]!r} is "
                              "the baseline already (one baseline per registry)")
    _METHODS[cls.name] = cls
    _SOURCES[cls.name] = source
    return cls


@contextlib.contextmanager
def _loading(source):
    _LOADING.append(source)
    try:
        yield
    finally:
        _LOADING.pop()


def _import(module, source):
    """Import a plug-in module; any failure becomes one :class:`PluginError` line naming the plug-in."""
    with _loading(source):
        try:
            return importlib.import_module(module)
        except PluginError:
            raise
        except ModuleNotFoundError as error:
            if error.name and module.startswith(error.name):
                raise PluginError(f"plug-in {source!r}: no module named {module!r} on the Python path (set "
                                  "PYTHONPATH, or install it)") from None
            raise PluginError(f"plug-in {source!r} fails to import: {type(error).__name__}: {error}") from None
        except Exception as error:  # a plug-in's import runs its own code
            raise PluginError(f"plug-in {source!r} fails to import: {type(error).__name__}: {error}") from None


def load_plugins(modules=()):
    """Import plug-in modules by name (``--plugin MODULE``); their decorated classes register.

    A module already imported is not imported again.

    Returns
    -------
    tuple of str
        The names of the methods these modules registered, in registration
        order (whether they were imported now or before).

    Raises
    ------
    PluginError
        A module that is not found or fails to import, a name clash, a broken contract.
    """
    _load_builtin()
    names = []
    for module in modules:
        if not isinstance(module, str) or not module.strip():
            raise PluginError(f"--plugin takes a module name such as my_methods, got {module!r}")
        names.append(module.strip())
        _import(names[-1], names[-1])
    return tuple(name for name, source in _SOURCES.items() if source in names)


def plugin_modules():
    """The modules of every registered method class defined outside sparselt (plug-ins, methods a script
    registered), in registration order: what another process imports to know the same methods."""
    _load_builtin()
    modules = []
    for cls in _METHODS.values():
        module = cls.__module__
        if module.split(".")[0] != "sparselt" and module != "__main__" and module not in modules:
            modules.append(module)
    return tuple(modules)


def method_names():
    """Registered method names, in registration order (built-ins first)."""
    _load_builtin()
    return tuple(_METHODS)


def method_source(name):
    """The module (or entry point) that registered ``name``; for ``METHOD+oidn``, the method's, then the composition's
    module."""
    _load_builtin()
    if name not in _SOURCES:
        cls = method_class(name)  # a composed name (an unknown one is refused, naming the registered methods)
        return f"{_SOURCES[cls.composes.name]} + {cls.__module__}"
    return _SOURCES[name]


def method_class(name):
    """The registered :class:`~sparselt.methods.base.Method` class called ``name``.

    Raises
    ------
    ValueError
        Unknown name; the message lists the registered methods. A name
        ``METHOD+oidn`` is the registered method followed by the denoiser
        (:func:`~sparselt.methods.composition.composed_class`).
    """
    _load_builtin()
    if name not in _METHODS:
        from .composition import composed_class, split_composition

        composition = split_composition(name)
        if composition is not None and composition[0] in _METHODS:
            return composed_class(_METHODS[composition[0]], composition[1])
        raise ValueError(f"unknown method {name!r}; registered methods: {', '.join(sorted(_METHODS))} "
                         "(a plug-in's method needs --plugin MODULE; any of them followed by a denoiser is "
                         "written METHOD+oidn)")
    return _METHODS[name]


def get_method(spec, *, grid_shape=None, options=None):
    """The estimator ``spec`` names: an instance of its method with its options resolved.

    Parameters
    ----------
    spec : str
        A method name (``cosamp``) or a variant (``cosamp:gamma=0.5``,
        :func:`~sparselt.methods.variants.parse_method_variant`); the
        instance's :attr:`~sparselt.methods.base.Method.label` is ``spec``.
    grid_shape : tuple of int, optional
        The comparison's grid, for options whose default or range depends on
        it (needed when the method has such options).
    options : mapping, optional
        The method's options before the variant's own (``--option
        METHOD.NAME=VALUE``); the variant's values win.

    Raises
    ------
    ValueError
        Unknown method (the message lists the registered ones), a malformed
        variant, an option the method does not declare or a value it refuses.
    TypeError
        A grid-dependent option and no ``grid_shape``.
    """
    from .variants import parse_method_variant

    name, given = parse_method_variant(spec)
    merged = dict(options or {})
    merged.update(given)
    cls = method_class(name)
    return cls(merged, grid_shape=grid_shape, label=spec.strip())


def baseline_name():
    """The name of the baseline method (``pt``)."""
    _load_builtin()
    return next(name for name, cls in _METHODS.items() if cls.baseline)


def resolve_method_options(name, given=None, *, grid_shape):
    """The resolved options of method ``name`` (see :func:`~sparselt.methods.options.resolve_options`)."""
    from .options import resolve_options

    return resolve_options(method_class(name).Options, given or {}, grid_shape=grid_shape, owner=name)


def _load_builtin():
    if not _STATE["builtin"]:
        _STATE["builtin"] = True
        from . import path_tracing  # noqa: F401,I001  (they register, in this order)
        from . import samples_mean  # noqa: F401
        from . import cosamp_reconstruction  # noqa: F401
        from . import filtered  # noqa: F401
        from . import nfor  # noqa: F401
        from . import sft_reconstruction  # noqa: F401
        from . import guided  # noqa: F401
        from . import wedge_cosamp  # noqa: F401
        from . import axis_aligned  # noqa: F401
        from . import gradient_domain  # noqa: F401
    if not _STATE["entry_points"]:
        _STATE["entry_points"] = True
        for entry in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
            _import(entry.value.split(":")[0], f"{entry.name} = {entry.value} (entry point)")


__all__ = ["ENTRY_POINT_GROUP", "PluginError", "baseline_name", "check_method_class", "get_method",
           "load_plugins", "method_class", "method_names", "method_source", "plugin_modules", "register",
           "resolve_method_options"]
