"""Hypothesis strategies shared by the fuzz tests: YAML-shaped values, hostile numbers and keys.

Strategies are built once (module level or cached) and only drawn from per case: building a
recursive strategy inside a ``@composite`` draw re-validates it on every case, which cost ~0.1 s a
case and kept the 10,000-case nightly run from finishing.
"""

from __future__ import annotations

import functools
import math
import random
from typing import Any

from hypothesis import strategies as st

#: Numbers that break naive code: NaN, infinities, huge, tiny, negative zero, big integers.
HOSTILE_NUMBERS = st.sampled_from([math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, -0.0, 0, -1,
                                   2**63, -(2**63), 2**200, 100_000, 0.5])
NUMBERS = st.one_of(HOSTILE_NUMBERS, st.floats(allow_nan=True, allow_infinity=True),
                    st.integers(min_value=-(2**70), max_value=2**70), st.floats(-20, 20))
TEXT = st.text(max_size=30)
SCALARS = st.one_of(st.none(), st.booleans(), NUMBERS, TEXT)


@functools.cache
def values(keys: st.SearchStrategy[str] = TEXT, depth: int = 3) -> st.SearchStrategy[Any]:
    """Any YAML-representable value: scalars, lists and mappings nested up to ``depth`` (built once)."""
    return st.recursive(SCALARS, lambda inner: st.one_of(
        st.lists(inner, max_size=5), st.dictionaries(keys, inner, max_size=5)), max_leaves=depth * 8)


def mutations(bases: list[Any]) -> st.SearchStrategy[Any]:
    """A copy of one of ``bases`` with some values replaced by hostile ones, keys dropped or added.

    Build it once (at import or in ``@given``), not inside a per-case draw. Where to mutate is
    decided by a seeded ``random.Random`` (one drawn seed a case, reproducible): Hypothesis's own
    randoms made every coin flip over a whole document a draw, most of a case's time.
    """
    return st.builds(_mutate, st.sampled_from(bases), st.integers(0, 2**32 - 1).map(random.Random),
                     st.lists(st.one_of(SCALARS, values(depth=2)), min_size=1, max_size=4),
                     st.lists(TEXT, min_size=1, max_size=3), st.sampled_from([0.02, 0.1, 0.3]))


def _mutate(base: Any, rng: Any, pool: list[Any], keys: list[str], rate: float) -> Any:
    if isinstance(base, dict):
        out = {}
        for key, value in base.items():
            roll = rng.random()
            if roll < rate / 2:
                continue  # drop the key
            out[key] = rng.choice(pool) if roll < rate else _mutate(value, rng, pool, keys, rate)
        if rng.random() < rate:
            out[rng.choice(keys)] = rng.choice(pool)
        return out
    if isinstance(base, list):
        items = [_mutate(v, rng, pool, keys, rate) for v in base if rng.random() >= rate / 2]
        if rng.random() < rate:
            items.insert(rng.randrange(len(items) + 1), rng.choice(pool))
        return items
    roll = rng.random()
    if roll < rate:
        return rng.choice(pool)
    if roll < 2 * rate and isinstance(base, int | float) and not isinstance(base, bool):
        return rng.choice(_HOSTILE)
    return base


_HOSTILE = [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, -0.0, 0, -1, 2**63, -(2**63), 2**200,
            100_000, 0.5]
