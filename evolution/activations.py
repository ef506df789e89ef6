"""The activations of evolved networks, compiled: float32 and the same bits in every kernel.

The dense layers (:mod:`evolution.networks`) and the convolutions
(:mod:`evolution.convolution`) apply them through :func:`activate`, so an
activation is computed the same way wherever it appears. tanh is a rational
approximation (Eigen's, within 4e-7 of the exact value): numba's ``np.tanh``
calls libm, whose result may differ between machines.
"""

from __future__ import annotations

import numba
import numpy as np

from amaze.agents.network_inputs import ACTIVATIONS

__all__ = ["ACTIVATIONS", "ACTIVATION_CODES", "activate", "activate_block", "tanh32"]

#: Their codes in the compiled kernels.
ACTIVATION_CODES = {name: code for code, name in enumerate(ACTIVATIONS)}
_TANH, _RELU, _SIGMOID, _IDENTITY = range(4)


@numba.njit(cache=True, error_model="numpy")
def tanh32(v):
    """float32 tanh: Eigen's rational approximation on [-7.9053, 7.9053], ±1 beyond."""
    c = np.float32(7.90531110763549805)
    x = v if v < c else c
    x = x if x > -c else -c
    x2 = x * x
    p = np.float32(-2.76076847742355e-16)
    p = x2 * p + np.float32(2.00018790482477e-13)
    p = x2 * p + np.float32(-8.60467152213735e-11)
    p = x2 * p + np.float32(5.12229709037114e-08)
    p = x2 * p + np.float32(1.48572235717979e-05)
    p = x2 * p + np.float32(6.37261928875436e-04)
    p = x2 * p + np.float32(4.89352455891786e-03)
    q = np.float32(1.19825839466702e-06)
    q = x2 * q + np.float32(1.18534705686654e-04)
    q = x2 * q + np.float32(2.26843463243900e-03)
    q = x2 * q + np.float32(4.89352518554385e-03)
    return x * p / q


@numba.njit(cache=True, error_model="numpy")
def activate(v, activation):
    """Activation number ``activation`` of one float32 value."""
    if activation == _TANH:
        return tanh32(v)
    if activation == _RELU:
        return v if v > 0 else np.float32(0.0)
    if activation == _SIGMOID:
        return np.float32(0.5) + np.float32(0.5) * tanh32(np.float32(0.5) * v)
    return v


@numba.njit(cache=True, error_model="numpy")
def activate_block(a, b, d_out, nb, activation):
    """``a = activation(b)`` on the first ``d_out x nb`` entries."""
    for o in range(d_out):
        if activation == _TANH:
            for r in range(nb):
                a[o, r] = tanh32(b[o, r])
        elif activation == _RELU:
            for r in range(nb):
                v = b[o, r]
                a[o, r] = v if v > 0 else np.float32(0.0)
        elif activation == _SIGMOID:
            for r in range(nb):
                a[o, r] = np.float32(0.5) + np.float32(0.5) * tanh32(np.float32(0.5) * b[o, r])
        else:
            for r in range(nb):
                a[o, r] = b[o, r]
