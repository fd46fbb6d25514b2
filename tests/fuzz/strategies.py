"""Hypothesis strategies shared by the fuzz tests: YAML-shaped values, hostile numbers and keys."""

from __future__ import annotations

import math
from typing import Any

from hypothesis import strategies as st

#: Numbers that break naive code: NaN, infinities, huge, tiny, negative zero, big integers.
HOSTILE_NUMBERS = st.sampled_from([math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, -0.0, 0, -1,
                                   2**63, -(2**63), 2**200, 100_000, 0.5])
NUMBERS = st.one_of(HOSTILE_NUMBERS, st.floats(allow_nan=True, allow_infinity=True),
                    st.integers(min_value=-(2**70), max_value=2**70), st.floats(-20, 20))
TEXT = st.text(max_size=30)
SCALARS = st.one_of(st.none(), st.booleans(), NUMBERS, TEXT)


def values(keys: st.SearchStrategy[str] = TEXT, depth: int = 3) -> st.SearchStrategy[Any]:
    """Any YAML-representable value: scalars, lists and mappings nested up to ``depth``."""
    return st.recursive(SCALARS, lambda inner: st.one_of(
        st.lists(inner, max_size=5), st.dictionaries(keys, inner, max_size=5)), max_leaves=depth * 8)


@st.composite
def mutations(draw: Any, bases: list[Any]) -> Any:
    """A copy of one of ``bases`` with some values replaced by hostile ones, keys dropped or added."""
    base = draw(st.sampled_from(bases))
    rng = draw(st.randoms(use_true_random=False))
    pool = draw(st.lists(st.one_of(SCALARS, values()), min_size=1, max_size=8))
    keys = draw(st.lists(TEXT, min_size=1, max_size=3))
    rate = draw(st.sampled_from([0.02, 0.1, 0.3]))
    return _mutate(base, rng, pool, keys, rate)


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
