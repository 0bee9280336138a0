"""The linear-operator abstraction in PyLops terms, its adjoint (dot) test, and the CoSaMP contract.

Operators follow PyLops (``pylops/linearoperator.py``): ``dims`` (model
shape), ``dimsd`` (data shape), ``shape = (prod(dimsd), prod(dims))``,
``dtype``, matrix-free :meth:`LinearOperator.matvec` (``A x``) and
:meth:`LinearOperator.rmatvec` (``A^* y``) on flat vectors, ``op @ x``, and
``op.H``, the adjoint as an operator. ``clinear`` is False for an operator that
is only real-linear (a real signal parametrised by complex half-spectrum
coordinates): its adjoint is taken in the real inner product ``Re <a, b>``,
and :func:`dottest` checks it there.

:class:`SupportRestricted` names the fast paths CoSaMP and OMP use besides
``matvec``/``rmatvec``: they touch only the coefficients of a support, never a
full coefficient vector.

References
----------
Ravasi, M. and Vasconcelos, I. (2020). PyLops, a linear-operator Python
library for scalable algebra and optimization. SoftwareX 11. Ong, F. and
Lustig, M. (2019). SigPy. Thesis 2.2.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np


class LinearOperator:
    """A matrix-free linear operator from a model of shape ``dims`` to data of shape ``dimsd``.

    Subclasses set ``dims``, ``dimsd``, ``dtype`` (the model's), ``clinear``
    and implement ``_matvec`` and ``_rmatvec`` on flat vectors.
    """

    dims: tuple
    dimsd: tuple
    dtype: np.dtype
    clinear: bool = True
    # ``data_dtype`` (optional): the data's dtype when it differs from the model's (real samples of
    # complex coefficients); ``dtype`` otherwise.

    def _matvec(self, vector):  # pragma: no cover - abstract
        raise NotImplementedError

    def _rmatvec(self, vector):  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def shape(self):
        """``(number of data values, number of model values)``."""
        return (math.prod(self.dimsd), math.prod(self.dims))

    def matvec(self, vector):
        """``A x`` for a model vector of ``shape[1]`` values (any shape with that many)."""
        return self._matvec(self._flat(vector, "matvec", "dims", self.dims))

    def rmatvec(self, vector):
        """``A^* y`` for a data vector of ``shape[0]`` values."""
        return self._rmatvec(self._flat(vector, "rmatvec", "dimsd", self.dimsd))

    def _flat(self, vector, method, name, dims):
        """``vector`` flattened, refused unless it has ``prod(dims)`` values."""
        vector = np.asarray(vector).reshape(-1)
        size = math.prod(dims)
        if vector.size != size:
            raise ValueError(f"{type(self).__name__}.{method} takes {size} values ({name} {tuple(dims)}), "
                             f"got {vector.size}")
        return vector

    @property
    def H(self):  # noqa: N802  (PyLops' name)
        """The adjoint as an operator: ``op.H.matvec(y) == op.rmatvec(y)``."""
        return AdjointOperator(self)

    def __matmul__(self, vector):
        return self.matvec(vector)


class AdjointOperator(LinearOperator):
    """``A^*`` of an operator ``A`` (what ``A.H`` returns); ``A.H.H`` is ``A`` again."""

    def __init__(self, operator):
        self.operator = operator
        self.dims, self.dimsd = operator.dimsd, operator.dims
        self.dtype = np.dtype(getattr(operator, "data_dtype", operator.dtype))  # the model of A^* is A's data
        self.data_dtype = np.dtype(operator.dtype)
        self.clinear = operator.clinear

    def _matvec(self, vector):
        return self.operator.rmatvec(vector)

    def _rmatvec(self, vector):
        return self.operator.matvec(vector)

    @property
    def H(self):  # noqa: N802
        return self.operator


@runtime_checkable
class SupportRestricted(Protocol):
    """What CoSaMP and OMP need from an operator besides ``matvec``/``rmatvec`` (see PartialFourier).

    ``transform_samples(r)`` returns the spectrum of a data vector (one full
    transform); ``proxy_energy(spectrum)`` the energy of ``A^* r`` per
    coefficient entry; ``adjoint_on(support, r, spectrum)`` and
    ``forward_on(support, values)`` the operator restricted to a support;
    ``coefficient_counts(support)`` how many full-spectrum coefficients each
    entry stands for; ``to_sparse_fourier(support, values)`` the result.
    """

    real: bool
    output_size: int
    input_size: int
    sample_dtype: np.dtype
    coefficient_dtype: np.dtype
    transforms: int

    def transform_samples(self, samples): ...

    def proxy_energy(self, spectrum): ...

    def adjoint_on(self, support, samples, spectrum=None): ...

    def forward_on(self, support, values): ...

    def coefficient_counts(self, support): ...

    def to_sparse_fourier(self, support, values): ...


def _random(rng, size, dtype):
    values = rng.standard_normal(size)
    if np.issubdtype(dtype, np.complexfloating):
        values = values + 1j * rng.standard_normal(size)
    return values.astype(dtype)


DEFAULT_RTOL = {np.dtype(np.float32): 1e-4, np.dtype(np.complex64): 1e-4,
                np.dtype(np.float64): 1e-10, np.dtype(np.complex128): 1e-10}


def dottest(operator, *, rtol=None, raise_error=True, seed=0, input_vector=None):
    """Dot (adjoint) test: ``<A x, y> = <x, A^* y>`` for random ``x`` and ``y`` (model: PyLops' ``dottest``).

    Parameters
    ----------
    operator : LinearOperator
    rtol : float, optional
        Tolerance on the relative mismatch; default from the operator's dtype
        (1e-4 single, 1e-10 double precision).
    raise_error : bool, optional
        Raise AssertionError when the mismatch exceeds ``rtol`` (default);
        otherwise return False.
    seed : int, optional
    input_vector : ndarray, optional
        Use this ``x`` instead of a random one.

    Returns
    -------
    bool
        True when the test passes.

    Notes
    -----
    For a complex-linear operator (``clinear``) both the real and imaginary
    parts of the inner products must agree; for a real-linear one only the
    real parts, the inner product in which its adjoint is defined.
    """
    rng = np.random.default_rng(seed)
    data_dtype = getattr(operator, "data_dtype", operator.dtype)
    x = input_vector if input_vector is not None else _random(rng, operator.shape[1], operator.dtype)
    y = _random(rng, operator.shape[0], data_dtype)
    forward = np.vdot(y.astype(np.complex128), np.asarray(operator.matvec(x)).astype(np.complex128))
    adjoint = np.vdot(np.asarray(operator.rmatvec(y)).astype(np.complex128), x.astype(np.complex128))
    if not operator.clinear:
        forward, adjoint = forward.real, adjoint.real
    mismatch = abs(forward - adjoint) / (abs(forward) + 1e-300)
    tolerance = rtol if rtol is not None else DEFAULT_RTOL.get(np.dtype(operator.dtype), 1e-6)
    if mismatch > tolerance:
        if raise_error:
            raise AssertionError(f"dot test failed: <Ax, y> = {forward:.6g}, <x, A^*y> = {adjoint:.6g}, relative "
                                 f"mismatch {mismatch:.3g} > {tolerance:.3g}")
        return False
    return True
