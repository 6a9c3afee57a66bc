"""A per-process memo of array results with a budget of bytes (:func:`memoised`).

The model's expensive pure functions — a family's unit modes (:mod:`ebb_model.modal.mode_family`), a grid's difference
operators (:mod:`ebb_model.space.discretisation`) — are computed once per key and process.  The memo keeps results up to
:data:`MEMO_BYTES` each, dropping the least recently used, so a result never depends on which calls came before:
a resumed run or another worker computes the same numbers.
"""
from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from collections.abc import Hashable
from dataclasses import dataclass
from typing import Any, Callable, TypeVar


__all__ = ["MEMO_BYTES", "MemoInfo", "memoised"]

T = TypeVar("T")
K = TypeVar("K", bound=Hashable)

#: Bytes of results each memo keeps per process (:func:`memoised`): a 50-node family's entry is about 0.3 MB, a
#: 1000-node one about 50 MB — hundreds of small families, or two of the largest grid.
MEMO_BYTES = 128 * 2 ** 20


@dataclass(frozen=True)
class MemoInfo:
    """What a memo did: ``hits``, ``misses``, the entries it keeps and their bytes."""

    hits: int
    misses: int
    entries: int
    nbytes: int


#: Types that hold no array (skipped at once by :func:`_nbytes`).
_SCALARS = (int, float, str, bool, type(None))


def _nbytes(value: Any) -> int:
    """The bytes of the arrays in ``value`` (an array, a dataclass or a tuple of them, nested; the fields of a
    dataclass, not its cached properties), or what an object says with an integer ``nbytes``."""
    total = 0
    stack = [value]
    while stack:
        v = stack.pop()
        kind = type(v)
        if kind in _SCALARS:
            continue
        size = getattr(v, "nbytes", None)    # an array, or a result that counts its own
        if isinstance(size, int):
            total += size
        elif isinstance(v, tuple):
            stack.extend(v)
        elif hasattr(kind, "__dataclass_fields__"):
            stack.extend(getattr(v, f) for f in kind.__dataclass_fields__)
    return total


def memoised(fn: Callable[[K], T]) -> Callable[[K], T]:
    """``fn`` memoised per process: the least recently used results dropped beyond :data:`MEMO_BYTES` (the
    newest always kept); ``cache_clear()`` and ``cache_info()`` as :func:`functools.lru_cache`'s."""
    entries: OrderedDict[K, tuple[T, int]] = OrderedDict()
    counts = {"hits": 0, "misses": 0, "nbytes": 0}
    lock = threading.Lock()

    @functools.wraps(fn)
    def wrapper(key: K) -> T:
        with lock:
            found = entries.get(key)
            if found is not None:
                entries.move_to_end(key)
                counts["hits"] += 1
                return found[0]
            counts["misses"] += 1
        value = fn(key)                      # outside the lock: another thread may compute the same, harmlessly
        size = _nbytes(value)
        with lock:
            old = entries.pop(key, None)
            counts["nbytes"] += size - (old[1] if old is not None else 0)
            entries[key] = (value, size)
            while len(entries) > 1 and counts["nbytes"] > MEMO_BYTES:
                counts["nbytes"] -= entries.popitem(last=False)[1][1]
        return value

    def cache_clear() -> None:
        with lock:
            entries.clear()
            counts.update(hits=0, misses=0, nbytes=0)

    def cache_info() -> MemoInfo:
        with lock:
            return MemoInfo(counts["hits"], counts["misses"], len(entries), counts["nbytes"])

    wrapper.cache_clear = cache_clear        # type: ignore[attr-defined]
    wrapper.cache_info = cache_info          # type: ignore[attr-defined]
    return wrapper
