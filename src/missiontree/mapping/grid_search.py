"""The planner's search kernels: resumable A*/Dijkstra over tiled state, a coarse guide, the trace back.

Loops over plain arrays, compiled by numba when the ``accel`` extra is installed and run as plain
Python otherwise (the same code both ways). :class:`missiontree.mapping.planner.Costmap` owns the
tiles and calls these; a kernel hands back to it with a request code (:data:`NEED_COST`,
:data:`NEED_STATE`, :data:`NEED_HEAP`) whenever it needs a cost tile or more room, and is called
again with the same state to resume. Cost values follow Nav2's costmap conventions.
"""

from __future__ import annotations

import numpy as np

try:  # numba is the ``accel`` extra; the loops below also run as plain Python
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised where numba is absent
    numba = None
    HAVE_NUMBA = False

LETHAL = 254
INSCRIBED = 253
NO_INFORMATION = 255
#: Highest cost a cell can have and still be entered.
MAX_FREE = 252
TILE_BITS = 6
TILE = 1 << TILE_BITS
TILE_MASK = TILE - 1

# search kernel return codes
FOUND, NONE, NEED_COST, NEED_STATE, NEED_HEAP = 0, 1, 2, 3, 4
# state vector slots
S_HEAP, S_SLOTS, S_TILE, S_LEFT, S_EXPANDED, S_REACHED = 0, 1, 2, 3, 4, 5
CLOSED = 16
BLOCK_BITS = 3
BLOCK = 1 << BLOCK_BITS
START = 8
#: Row and column steps to the eight neighbours of a cell.
_DRS = (-1, -1, -1, 0, 0, 1, 1, 1)
_DCS = (-1, 0, 1, -1, 1, -1, 0, 1)


def _sift_down_py(heap_k, heap_v, size):  # noqa: ANN001, ANN202
    """Sift the root of the min-heap (keys ``heap_k``, values ``heap_v``, ``size`` entries) down."""
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            return
        child = left
        if left + 1 < size and heap_k[left + 1] < heap_k[left]:
            child = left + 1
        if not heap_k[child] < heap_k[i]:
            return
        tk = heap_k[i]
        heap_k[i] = heap_k[child]
        heap_k[child] = tk
        tv = heap_v[i]
        heap_v[i] = heap_v[child]
        heap_v[child] = tv
        i = child


def _push_py(heap_k, heap_v, size, key, value):  # noqa: ANN001, ANN202
    """Add ``key``/``value`` as entry ``size`` of the min-heap and sift it up (room must exist)."""
    j = size
    heap_k[j] = key
    heap_v[j] = value
    while j > 0:
        up = (j - 1) // 2
        if not heap_k[up] > heap_k[j]:
            return
        tk = heap_k[up]
        heap_k[up] = heap_k[j]
        heap_k[j] = tk
        tv = heap_v[up]
        heap_v[up] = heap_v[j]
        heap_v[j] = tv
        j = up


def _missing_tile_py(cost_slot, r, c, h, w, ntc):  # noqa: ANN001, ANN202
    """The first cost tile around cell (r, c) that is not loaded yet, or -1."""
    for tr in range(max(r - 1, 0) >> TILE_BITS, (min(r + 1, h - 1) >> TILE_BITS) + 1):
        for tc in range(max(c - 1, 0) >> TILE_BITS, (min(c + 1, w - 1) >> TILE_BITS) + 1):
            if cost_slot[tr * ntc + tc] < 0:
                return tr * ntc + tc
    return -1


def _room_needed_py(g_pool, heap_k, state):  # noqa: ANN001, ANN202
    """The request for more room an expansion needs first (state tiles, heap entries), or -1."""
    if g_pool.shape[0] - state[S_SLOTS] < 4:
        return NEED_STATE
    if heap_k.shape[0] - state[S_HEAP] < 9:
        return NEED_HEAP
    return -1


def _lower_bound_py(goals, cur):  # noqa: ANN001, ANN202
    """The first index of the sorted ``goals`` whose value is not below ``cur`` (a binary search)."""
    lo = 0
    hi = goals.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if goals[mid] < cur:
            lo = mid + 1
        else:
            hi = mid
    return lo


def _estimate_py(nr, nc, gr, gc, coarse, cfar):  # noqa: ANN001, ANN202
    """A*'s estimate from (nr, nc) to the goal (gr, gc), in cells.

    The octile distance (exact on an empty 8-connected grid) or, when larger, the coarse distance
    around obstacles less a block's slack.
    """
    ar = abs(nr - gr)
    ac = abs(nc - gc)
    est = max(ar, ac) + 0.41421356237309515 * min(ar, ac)
    hc = coarse[nr >> BLOCK_BITS, nc >> BLOCK_BITS]
    if hc == np.inf:
        hc = cfar
    hc = (hc - 1.5) * BLOCK
    if hc > est:
        est = hc
    return est


# The kernels below call the heap steps by these names: compiled (inlined into each kernel) with
# numba, plain Python without it.
if HAVE_NUMBA:
    _sift_down = numba.njit(cache=True, nogil=True, inline="always")(_sift_down_py)
    _push = numba.njit(cache=True, nogil=True, inline="always")(_push_py)
    _missing_tile = numba.njit(cache=True, nogil=True, inline="always")(_missing_tile_py)
    _lower_bound = numba.njit(cache=True, nogil=True, inline="always")(_lower_bound_py)
    _room_needed = numba.njit(cache=True, nogil=True, inline="always")(_room_needed_py)
    _estimate = numba.njit(cache=True, nogil=True, inline="always")(_estimate_py)
else:  # pragma: no cover - exercised where numba is absent
    _sift_down, _push = _sift_down_py, _push_py
    _missing_tile, _lower_bound, _estimate = _missing_tile_py, _lower_bound_py, _estimate_py
    _room_needed = _room_needed_py


def _pop_py(heap_k, heap_v, state):  # noqa: ANN001, ANN202
    """Remove the min-heap's root (its size in ``state[S_HEAP]``)."""
    size = state[S_HEAP] - 1
    state[S_HEAP] = size
    heap_k[0] = heap_k[size]
    heap_v[0] = heap_v[size]
    _sift_down(heap_k, heap_v, size)


def _new_slot_py(g_slot, g_pool, par_pool, state, tile):  # noqa: ANN001, ANN202
    """Give ``tile`` the next free state slot, its cells unreached (g = inf, no parent); the slot."""
    slot = state[S_SLOTS]
    state[S_SLOTS] = slot + 1
    g_slot[tile] = slot
    for j in range(TILE * TILE):
        g_pool[slot, j] = np.inf
        par_pool[slot, j] = -1
    return slot


def _cost_to_enter_py(cost_pool, cost_slot, nr, nc, sr, sc, escape2):  # noqa: ANN001, ANN202
    """Cell (nr, nc)'s cost (its tile in ``cost_slot``); inscribed cells near the start (sr, sc) cost less."""
    cost = cost_pool[cost_slot, nr & TILE_MASK, nc & TILE_MASK]
    if cost == INSCRIBED and (nr - sr) * (nr - sr) + (nc - sc) * (nc - sc) <= escape2:
        return MAX_FREE  # the robot may leave the inscribed zone it stands in
    return cost


if HAVE_NUMBA:
    _pop = numba.njit(cache=True, nogil=True, inline="always")(_pop_py)
    _new_slot = numba.njit(cache=True, nogil=True, inline="always")(_new_slot_py)
    _cost_to_enter = numba.njit(cache=True, nogil=True, inline="always")(_cost_to_enter_py)
else:  # pragma: no cover - exercised where numba is absent
    _pop, _new_slot, _cost_to_enter = _pop_py, _new_slot_py, _cost_to_enter_py


def search_loops(cost_slot, cost_pool, g_slot, g_pool, l_pool, par_pool, heap_k, heap_v,  # noqa: ANN001, ANN201, PLR0912, PLR0913, PLR0915
                  state, h, w, ntc, sr, sc, escape2, goals, weight, heuristic, hweight, coarse, cfar):
    """Resumable A* (``heuristic``) or Dijkstra to every cell in sorted ``goals`` (flat indices).

    Returns a code: found, none, or a request (cost tile ``state[S_TILE]``, more state tiles,
    a bigger heap) after which Python provides what was asked and calls again with the same state.
    """
    gr, gc = goals[0] // w, goals[0] % w  # A*'s goal: the first
    while state[S_HEAP] > 0:
        cur = heap_v[0]
        r, c = cur // w, cur % w
        slot = g_slot[(r >> TILE_BITS) * ntc + (c >> TILE_BITS)]
        off = (r & TILE_MASK) * TILE + (c & TILE_MASK)
        closed = par_pool[slot, off] >= CLOSED
        if not closed:
            # everything the expansion will need, before popping (so a request can resume here)
            missing = _missing_tile(cost_slot, r, c, h, w, ntc)
            if missing >= 0:
                state[S_TILE] = missing
                return NEED_COST
            room = _room_needed(g_pool, heap_k, state)
            if room >= 0:
                return room
        _pop(heap_k, heap_v, state)
        if closed:
            continue
        par_pool[slot, off] += CLOSED
        state[S_EXPANDED] += 1
        g_cur, l_cur = g_pool[slot, off], l_pool[slot, off]
        lo = _lower_bound(goals, cur)
        if lo < goals.shape[0] and goals[lo] == cur:
            state[S_REACHED] += 1
            state[S_LEFT] -= 1
            if state[S_LEFT] <= 0:
                return FOUND
        for k in range(8):
            nr, nc = r + _DRS[k], c + _DCS[k]
            if nr < 0 or nr >= h or nc < 0 or nc >= w:
                continue
            ntile = (nr >> TILE_BITS) * ntc + (nc >> TILE_BITS)
            noff = (nr & TILE_MASK) * TILE + (nc & TILE_MASK)
            cost = _cost_to_enter(cost_pool, cost_slot[ntile], nr, nc, sr, sc, escape2)
            if cost > MAX_FREE:
                continue
            nslot = g_slot[ntile]
            if nslot < 0:
                nslot = _new_slot(g_slot, g_pool, par_pool, state, ntile)
            elif par_pool[nslot, noff] >= CLOSED:
                continue
            step = 1.4142135623730951 if _DRS[k] != 0 and _DCS[k] != 0 else 1.0  # diagonal or straight
            ng = g_cur + step * (1.0 + weight * cost / 252.0)
            if ng < g_pool[nslot, noff]:
                g_pool[nslot, noff] = ng
                l_pool[nslot, noff] = l_cur + step
                par_pool[nslot, noff] = k
                # A*: the estimate a hair heavier breaks ties toward deeper cells (no plateau floods)
                f = ng + _estimate(nr, nc, gr, gc, coarse, cfar) * hweight if heuristic else ng
                _push(heap_k, heap_v, state[S_HEAP], f, nr * w + nc)
                state[S_HEAP] += 1
    return NONE


def coarse_loops(blocked, goal, start, dist, heap_k, heap_v):  # noqa: ANN001, ANN201
    """Dijkstra in blocks from ``goal`` over the coarse grid until ``start`` is settled; its distance.

    ``dist`` (inf on entry) receives the settled distances in blocks; returns inf when the start
    cannot be reached at this scale (the fine search then uses the octile distance alone).
    """
    h, w = blocked.shape
    drs = (-1, -1, -1, 0, 0, 1, 1, 1)
    dcs = (-1, 0, 1, -1, 1, -1, 0, 1)
    tent = np.full(h * w, np.inf, np.float32)
    size = 1
    heap_k[0] = 0.0
    heap_v[0] = goal
    tent[goal] = 0.0
    while size > 0:
        key = heap_k[0]
        cur = heap_v[0]
        size -= 1
        heap_k[0] = heap_k[size]
        heap_v[0] = heap_v[size]
        _sift_down(heap_k, heap_v, size)
        r, c = cur // w, cur % w
        if dist[r, c] != np.inf:
            continue
        dist[r, c] = key
        if cur == start:
            return key
        for k in range(8):
            nr, nc = r + _DRS[k], c + _DCS[k]
            if nr < 0 or nr >= h or nc < 0 or nc >= w or blocked[nr, nc] or dist[nr, nc] != np.inf:
                continue
            nk = key + (1.4142135623730951 if drs[k] != 0 and dcs[k] != 0 else 1.0)
            nxt = nr * w + nc
            if nk >= tent[nxt]:
                continue
            tent[nxt] = nk
            if size >= heap_k.shape[0]:
                return np.inf  # out of room: fall back to the octile distance
            _push(heap_k, heap_v, size, nk, nxt)
            size += 1
    return np.inf


def trace_loops(g_slot, par_pool, w, ntc, start, goal):  # noqa: ANN001, ANN201
    """The cells from ``goal`` back to ``start`` (goal first), following the steps stored in the search."""
    drs = (-1, -1, -1, 0, 0, 1, 1, 1)
    dcs = (-1, 0, 1, -1, 1, -1, 0, 1)
    n = 0
    cur = goal
    out = np.empty(1024, np.int64)
    while True:
        if n >= out.shape[0]:
            bigger = np.empty(out.shape[0] * 2, np.int64)
            bigger[:n] = out[:n]
            out = bigger
        out[n] = cur
        n += 1
        if cur == start:
            break
        r, c = cur // w, cur % w
        k = par_pool[g_slot[(r >> TILE_BITS) * ntc + (c >> TILE_BITS)],
                     (r & TILE_MASK) * TILE + (c & TILE_MASK)] % CLOSED
        cur = (r - drs[k]) * w + (c - dcs[k])
    return out[:n]


if HAVE_NUMBA:
    search_jit = numba.njit(cache=True, nogil=True)(search_loops)
    trace_jit = numba.njit(cache=True, nogil=True)(trace_loops)
    coarse_jit = numba.njit(cache=True, nogil=True)(coarse_loops)
else:  # pragma: no cover
    search_jit, trace_jit, coarse_jit = search_loops, trace_loops, coarse_loops
