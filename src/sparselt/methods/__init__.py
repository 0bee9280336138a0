"""Equal-time comparison methods: one module per method, one registry, plug-ins (thesis chapters 6, 8).

The public API for a method of one's own::

    from dataclasses import dataclass
    from sparselt.methods import Method, MethodOptions, MethodResult, PhaseTimer, option, register

    @dataclass(frozen=True)
    class MyOptions(MethodOptions):
        groups: int = option(4, minimum=2, maximum=64, help="groups of the median of means")

    @register
    class MyMethod(Method):
        name = "my-method"
        kinds = ("dof", "indirect", "path")
        Options = MyOptions
        def run(self, context, budget): ...

See :mod:`sparselt.methods.base` for the interface, :mod:`sparselt.methods.options`
for declared options, :mod:`sparselt.methods.registry` for plug-ins and
:mod:`sparselt.methods.contract` for the checks every method passes.
"""

from .base import TIME_PHASES, Budget, ComparisonContext, Method, MethodResult, PhaseTimer
from .options import MethodOptions, Option, option, resolve_options
from .registry import (
    ENTRY_POINT_GROUP,
    PluginError,
    baseline_name,
    get_method,
    load_plugins,
    method_names,
    register,
    resolve_method_options,
)

__all__ = ["ENTRY_POINT_GROUP", "TIME_PHASES", "Budget", "ComparisonContext", "Method", "MethodOptions",
           "MethodResult", "Option", "PhaseTimer", "PluginError", "baseline_name", "get_method", "load_plugins",
           "method_names", "option", "register", "resolve_method_options", "resolve_options"]
