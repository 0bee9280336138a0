"""Equal-time comparison methods: one module per method, one registry, plug-ins (thesis chapters 6, 8).

The public API for a method of one's own::

    from dataclasses import dataclass
    from sparselt.methods import Method, MethodOptions, MethodResult, ThinLens, get_method, option, register

    @dataclass(frozen=True)
    class MyOptions(MethodOptions):
        groups: int = option(4, minimum=2, maximum=64, help="groups of the median of means")

    @register
    class MyMethod(Method):
        name = "my-method"
        kinds = ("dof", "indirect", "path")
        Options = MyOptions
        requires = (ThinLens(),)  # checked before anything renders

        def run(self, context, budget, timer):
            with timer("sampling"):
                ...
            return MethodResult(image=image, path_samples=samples)

    MyMethod({"groups": 8}).options.groups        # an instance carries its options
    get_method("my-method:groups=8").options.groups   # the same, from a variant's text

See :mod:`sparselt.methods.base` for the interface, :mod:`sparselt.methods.options`
for declared options, :mod:`sparselt.methods.preconditions` for requirements,
:mod:`sparselt.methods.variants` for ``METHOD:NAME=VALUE`` variants,
:mod:`sparselt.methods.registry` for plug-ins and :mod:`sparselt.methods.contract`
for the checks every method passes.
"""

from .base import (TIME_PHASES, WARM_UP_SEED, Budget, ComparisonContext, Method, MethodResult, PhaseTimer,
                   collect_recent_garbage, run_timed, warm_up)
from .options import MethodOptions, Option, option, resolve_options
from .preconditions import (
    FilmResolution,
    GridMemory,
    MethodSetup,
    MinimumSpp,
    Requirement,
    ResolutionMultiple,
    ThinLens,
    TileDividesGrid,
)
from .registry import (
    ENTRY_POINT_GROUP,
    PluginError,
    baseline_name,
    get_method,
    load_plugins,
    method_class,
    method_names,
    plugin_modules,
    register,
    resolve_method_options,
)
from .variants import parse_method_variant, variant_file_name

__all__ = ["ENTRY_POINT_GROUP", "TIME_PHASES", "WARM_UP_SEED", "Budget", "ComparisonContext", "FilmResolution",
           "GridMemory", "Method", "MethodOptions", "MethodResult", "MethodSetup", "MinimumSpp", "Option", "PhaseTimer",
           "PluginError", "Requirement", "ResolutionMultiple", "ThinLens", "TileDividesGrid", "baseline_name",
           "collect_recent_garbage", "get_method", "load_plugins", "method_class", "method_names", "plugin_modules",
           "option", "parse_method_variant", "register", "resolve_method_options", "resolve_options", "run_timed",
           "variant_file_name", "warm_up"]
