"""Checkpoint state as flat ``name -> ndarray`` dictionaries (what :func:`numpy.savez` stores without pickle).

Every stateful part of a run (the evidence buffer, the filter, the tracker, the evidence sources, the run's
report) has ``state_dict()`` returning such a dictionary and ``load_state_dict(d)`` restoring it; the parts
of a larger object are stored under dotted prefixes (``"bof.occ_v"``). Nothing is pickled, so a checkpoint
read from an untrusted folder cannot run code.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

StateDict = dict[str, np.ndarray]


def with_prefix(prefix: str, state: Mapping[str, np.ndarray]) -> StateDict:
    """``state`` with every key prefixed ``prefix + "."``."""
    return {f"{prefix}.{k}": v for k, v in state.items()}


def sub_state(state: Mapping[str, np.ndarray], prefix: str) -> StateDict:
    """The entries of ``state`` under ``prefix + "."``, with the prefix removed."""
    p = prefix + "."
    return {k[len(p):]: v for k, v in state.items() if k.startswith(p)}


def get(state: Mapping[str, np.ndarray], key: str, owner: str) -> np.ndarray:
    """``state[key]``, or a ValueError naming what is missing and whose state it is."""
    try:
        return np.asarray(state[key])
    except KeyError:
        raise ValueError(f"{owner} state: entry {key!r} is missing (checkpoint from another version?)") from None


def get_shaped(state: Mapping[str, np.ndarray], key: str, shape: tuple[int, ...], owner: str) -> np.ndarray:
    """``state[key]`` checked to have ``shape`` (ValueError naming the entry otherwise)."""
    a = get(state, key, owner)
    if a.shape != tuple(shape):
        raise ValueError(f"{owner} state: {key!r} has shape {a.shape}, expected {tuple(shape)} (a checkpoint of "
                         "another configuration?)")
    return a


def optional_float(x: float | None) -> np.ndarray:
    """A float or None as a 0-d array (None is NaN)."""
    return np.asarray(np.nan if x is None else float(x))


def float_or_none(a: np.ndarray) -> float | None:
    """Inverse of :func:`optional_float`."""
    v = float(a)
    return None if np.isnan(v) else v


def strings(items: Sequence[str]) -> np.ndarray:
    """Strings as a unicode array (stored without pickle)."""
    return np.asarray(list(items), dtype=str) if len(items) else np.zeros(0, dtype="<U1")


def pack_ragged(arrays: Sequence[np.ndarray], tail_shape: tuple[int, ...], dtype=float) -> tuple[np.ndarray,
                                                                                                    np.ndarray]:
    """Arrays of shape ``(n_i, *tail_shape)`` as one concatenation and the ``n_i`` (for :func:`unpack_ragged`)."""
    counts = np.array([len(a) for a in arrays], dtype=np.int64)
    flat = (np.concatenate([np.asarray(a, dtype=dtype).reshape((-1, *tail_shape)) for a in arrays])
            if len(arrays) else np.zeros((0, *tail_shape), dtype=dtype))
    return flat, counts


def unpack_ragged(flat: np.ndarray, counts: np.ndarray) -> list[np.ndarray]:
    """Inverse of :func:`pack_ragged`."""
    ends = np.cumsum(counts)
    if len(counts) and ends[-1] != len(flat):
        raise ValueError(f"ragged state: counts sum to {int(ends[-1])} but there are {len(flat)} rows")
    return [flat[e - n:e] for n, e in zip(counts, ends)]
