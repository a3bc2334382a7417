"""Counter-based random streams: sample ``i``'s numbers depend only on the seed and ``i``.

The reliability estimators draw their standard-normal inputs here, so that an estimate does not
depend on how its samples are cut into batches: sample ``i``, dimension ``j`` of seed ``s`` is the
same number whether it is drawn alone, in a batch of 7 or in one batch of a million.

Each value is a hash of ``(seed, i, j)`` built from SplitMix64 (Steele, Lea & Flood 2014, "Fast
splittable pseudorandom number generators", OOPSLA; the output function of Java's
``SplittableRandom``), computed in numpy ``uint64`` arithmetic:

- the seed's key is SplitMix64's first output for the state ``seed``;
- sample ``i`` gets the state ``mix(key + (i + 1) * gamma)``, SplitMix64's ``i + 1``-th output
  from the key, where ``gamma`` is SplitMix64's odd increment ``0x9E3779B97F4A7C15``;
- dimension ``j`` of sample ``i`` is ``mix(state_i + (j + 1) * gamma)``, the ``j + 1``-th output
  of a SplitMix64 generator started at ``state_i``.

The top 52 of the 64 bits make the uniform ``(k + 1/2) / 2**52`` with ``k`` in ``[0, 2**52)``:
every such value is a float64 exactly, lies in the open interval (0, 1) (from ``2**-53`` to
``1 - 2**-53``), and the lattice is symmetric about 1/2, so ``1 - u`` is a possible ``u``. (53 bits
cannot do this: ``(k + 1/2) / 2**53`` needs 54 significant bits and rounds to 1 at the top.)
:func:`scipy.special.ndtri` takes it to a standard normal; its values lie within +-8.21, so
the streams resolve tail probabilities down to about ``1e-16``, far below the ``1e-9`` of the
ETCS safety margins.

Why not numpy's Philox with a counter per sample: arbitrary sample numbers need a generator object
per sample, about 11 microseconds each (measured), 4.5 million normals per second at 50
dimensions and far fewer at a few dimensions. The hash, measured on the 2-core development machine
(numpy 2.4, scipy 1.17, batches of 4096 samples x 50 dimensions): about 60 million uniforms and
35 million standard normals per second (:func:`scipy.special.ndtri` takes about half of the latter
time), negligible next to any braking model.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy.special import ndtri

_MASK64 = (1 << 64) - 1
_GAMMA = 0x9E3779B97F4A7C15
_MIX1 = 0xBF58476D1CE4E5B9
_MIX2 = 0x94D049BB133111EB
_UNIFORM_BITS = 52


def uniforms(seed: int, sample_index: np.ndarray, dims: int) -> np.ndarray:
    """Uniforms in the open interval (0, 1), ``dims`` per sample, counter-based.

    Parameters
    ----------
    seed
        The stream: an integer in ``[0, 2**64)``.
    sample_index
        The samples to draw (non-negative integers, any order, repeats allowed); row ``r`` of the
        result belongs to sample ``sample_index[r]``.
    dims
        How many values per sample; value ``j`` of a sample is the same whatever ``dims`` is
        (the first 10 of 50 are the 10 of 10).

    Returns
    -------
    numpy.ndarray
        Shape ``(len(sample_index), dims)``, float64, values ``(k + 1/2) / 2**52``.
    """
    bits = _hash_bits(seed, sample_index, dims)
    values = (bits >> np.uint64(64 - _UNIFORM_BITS)).astype(np.float64)
    values += 0.5
    values *= 2.0**-_UNIFORM_BITS
    return values


def standard_normals(seed: int, sample_index: np.ndarray, dims: int) -> np.ndarray:
    """Standard normals, ``dims`` per sample: :func:`scipy.special.ndtri` of :func:`uniforms`.

    Sample ``i``'s values depend only on ``(seed, i, j)``, so any chunking of the indices gives
    the same numbers bit for bit. Parameters as for :func:`uniforms`.

    Returns
    -------
    numpy.ndarray
        Shape ``(len(sample_index), dims)``, float64.
    """
    values = uniforms(seed, sample_index, dims)
    ndtri(values, out=values)
    return values


def derived_seed(seed: int, *path: int) -> int:
    """A seed for an independent stream derived from ``seed`` and a path of non-negative integers
    (``derived_seed(7, 1, 3)``: stream 1, level 3 of seed 7), by hashing each element in turn.

    The estimators take their auxiliary randomness (Markov-chain proposals, importance-sampling
    runs) from streams derived from the user's seed, so that one seed determines everything and the
    auxiliary streams do not repeat the seed's own samples.
    """
    key = _check_seed(seed)
    for position, element in enumerate(path):
        if not isinstance(element, numbers.Integral) or isinstance(element, bool) or element < 0:
            raise ValueError(f"path[{position}] = {element!r}: need a non-negative integer")
        key = _mix_int(key ^ _mix_int((int(element) + 1) * _GAMMA & _MASK64))
    return key


def _check_seed(seed: int) -> int:
    if not isinstance(seed, numbers.Integral) or isinstance(seed, bool) or not 0 <= seed <= _MASK64:
        raise ValueError(f"seed = {seed!r}: need an integer in [0, 2**64)")
    return int(seed)


def _mix_int(value: int) -> int:
    """SplitMix64's output function on a Python integer (for the scalar keys)."""
    value &= _MASK64
    value = ((value ^ (value >> 30)) * _MIX1) & _MASK64
    value = ((value ^ (value >> 27)) * _MIX2) & _MASK64
    return value ^ (value >> 31)


def _mix_array(values: np.ndarray) -> np.ndarray:
    """SplitMix64's output function, in place on a uint64 array (numpy wraps uint64 products)."""
    values ^= values >> np.uint64(30)
    values *= np.uint64(_MIX1)
    values ^= values >> np.uint64(27)
    values *= np.uint64(_MIX2)
    values ^= values >> np.uint64(31)
    return values


def _hash_bits(seed: int, sample_index: np.ndarray, dims: int) -> np.ndarray:
    """The 64-bit hashes of ``(seed, i, j)`` for each index ``i`` and dimension ``j < dims``."""
    key = _mix_int(_check_seed(seed) + _GAMMA)
    if not isinstance(dims, numbers.Integral) or isinstance(dims, bool) or dims < 1:
        raise ValueError(f"dims = {dims!r}: need an integer >= 1")
    index = np.asarray(sample_index)
    if index.ndim != 1:
        raise ValueError(f"sample_index has shape {index.shape}: need a 1-D array of sample numbers")
    if index.size and not np.issubdtype(index.dtype, np.integer):
        raise ValueError(f"sample_index has dtype {index.dtype}: need integers")
    if index.size and index.min() < 0:
        raise ValueError(f"sample_index holds {index.min()}: sample numbers are non-negative")
    states = index.astype(np.uint64)
    states += np.uint64(1)
    states *= np.uint64(_GAMMA)
    states += np.uint64(key)
    _mix_array(states)
    increments = (np.arange(1, int(dims) + 1, dtype=np.uint64) * np.uint64(_GAMMA))[None, :]
    bits = states[:, None] + increments
    return _mix_array(bits)
