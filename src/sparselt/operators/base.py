"""The linear-operator abstraction and its adjoint (dot) test.

Operators follow PyLops and sigpy: matrix-free ``forward`` (``A x``) and
``adjoint`` (``A^* y``) on flat vectors of fixed sizes, with the adjoint taken
in the *real* inner product ``Re <a, b>`` when an operator is only
real-linear (a real signal parametrised by complex half-spectrum
coefficients).
"""

from __future__ import annotations

import numpy as np


class LinearOperator:
    """A matrix-free linear operator from ``input_size`` to ``output_size`` values.

    Subclasses implement :meth:`forward` and :meth:`adjoint` and set
    ``input_size``, ``output_size``, ``input_dtype`` and ``output_dtype``.
    """

    input_size: int
    output_size: int
    input_dtype: np.dtype
    output_dtype: np.dtype

    def forward(self, vector):  # pragma: no cover - abstract
        raise NotImplementedError

    def adjoint(self, vector):  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def shape(self):
        return (self.output_size, self.input_size)

    def __matmul__(self, vector):
        return self.forward(vector)


def _random(rng, size, dtype):
    values = rng.standard_normal(size)
    if np.issubdtype(dtype, np.complexfloating):
        values = values + 1j * rng.standard_normal(size)
    return values.astype(dtype)


def dot_test(operator, *, seed=0, input_vector=None):
    """Relative mismatch of ``Re <A x, y>`` and ``Re <x, A^* y>`` for random ``x``, ``y``.

    Returns
    -------
    float
        ``|<Ax, y> - <x, A^*y>| / (|<Ax, y>| + tiny)``; near machine epsilon
        of the operator's dtype when the adjoint is right.
    """
    rng = np.random.default_rng(seed)
    x = input_vector if input_vector is not None else _random(rng, operator.input_size, operator.input_dtype)
    y = _random(rng, operator.output_size, operator.output_dtype)
    forward = np.vdot(y.astype(np.complex128), operator.forward(x).astype(np.complex128)).real
    adjoint = np.vdot(operator.adjoint(y).astype(np.complex128), x.astype(np.complex128)).real
    return abs(forward - adjoint) / (abs(forward) + 1e-300)
