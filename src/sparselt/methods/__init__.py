"""Equal-time comparison methods: one module per method, one registry (thesis chapters 6, 8).

``pt`` (path_tracing), ``samples-mean`` (samples_mean), ``cosamp`` and
``cosamp-thesis`` (cosamp_reconstruction). See :mod:`sparselt.methods.base`
for the interface.
"""

from .base import TIME_PHASES, Budget, ComparisonContext, Method, MethodResult, PhaseTimer
from .registry import get_method, method_names, register

__all__ = ["TIME_PHASES", "Budget", "ComparisonContext", "Method", "MethodResult", "PhaseTimer", "get_method",
           "method_names", "register"]
