"""The run viewer: one self-contained HTML file (no network, no CDN) built from a run directory.

The page is the viewer's script and style (``assets/viewer.js``, ``assets/viewer.css``) with the
run's data inlined as one JSON document, encoded compactly so that an hour of ticks (36,000)
stays a few megabytes and opens in about a second:

- strings (feedback, reasons, blackboard values, event fields) are interned in one table;
- node status changes are a flat integer list (tick delta, node, status, feedback, reason), from
  which the page builds keyframes (a full snapshot every 256 ticks) when it opens, so seeking to
  any tick applies at most 255 ticks of changes;
- root status per tick is one character a tick; times are milliseconds, delta-coded;
- the map is a PNG, alarm frames are small JPEGs (capped in number and bytes);
- the scene graph the run left (``scene_graph.json``) is a layer of labelled objects and rooms,
  with the mission's target (the object served or found) marked.

:func:`page_data` is the payload (also what ``view --follow`` serves as ``data.json``);
:func:`render_page` wraps it in the page; :func:`write_page` does both for a run directory.
"""

from __future__ import annotations

import base64
import json
import math
from importlib import resources
from pathlib import Path
from typing import Any

from missiontree.runlog.btlog import node_conditions
from missiontree.runlog.replay import (
    STATUSES,
    UNSET,
    Replay,
    event_category,
    event_position,
    open_run,
    read_runview,
)

#: Alarm and detection frames embedded at most (the rest are listed without a picture).
MAX_FRAMES = 200
#: Bytes of embedded frames at most.
MAX_FRAME_BYTES = 3_000_000
#: Event categories, in the order the page colours them.
CATEGORIES = ("goal", "alarm", "model", "failure", "detection", "other")
#: Scene-graph objects drawn at most (a run's graph rarely holds more than a few hundred).
MAX_SCENE_OBJECTS = 2000
#: The events whose position is the object a search found.
FOUND_EVENTS = ("object_found",)


class _Strings:
    """A string table: each distinct string stored once, referred to by index (0 is "")."""

    def __init__(self) -> None:
        self.items: list[str] = [""]
        self._index: dict[str, int] = {"": 0}

    def __call__(self, text: str) -> int:
        found = self._index.get(text)
        if found is None:
            found = self._index[text] = len(self.items)
            self.items.append(text)
        return found


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def run_map(run_dir: Path | None) -> dict[str, Any] | None:
    """The map a run directory offers: a learned ``map.pgm`` + ``map.yaml``, else the recorded one."""
    return _map_of(run_dir, read_runview(run_dir) if run_dir is not None else {})


def _map_of(run_dir: Path | None, runview: dict[str, Any]) -> dict[str, Any] | None:
    """The map to draw: a learned ``map.pgm`` + ``map.yaml`` in the run directory, else the recorded one."""
    if run_dir is not None and (run_dir / "map.yaml").is_file():
        learned = _read_map_server(run_dir / "map.yaml")
        if learned is not None:
            return learned
    found = runview.get("map")
    return found if isinstance(found, dict) and "png" in found else None


def _read_map_server(yaml_path: Path) -> dict[str, Any] | None:
    """A map_server map (YAML + image) as the page's map, or None when it cannot be read."""
    import cv2
    import numpy as np

    from missiontree.runlog.record import encode_map
    from missiontree.yamlio import load_yaml

    try:
        meta = load_yaml(yaml_path).data
        image = cv2.imread(str(yaml_path.parent / str(meta["image"])), cv2.IMREAD_GRAYSCALE)
        resolution = float(meta["resolution"])
        origin = [float(v) for v in meta.get("origin", [0.0, 0.0, 0.0])[:2]]
    except Exception:  # noqa: BLE001 - an unreadable map: fall back to the recorded one
        return None
    if image is None:
        return None
    negate = int(meta.get("negate", 0))
    occupied_at = float(meta.get("occupied_thresh", 0.65))
    free_at = float(meta.get("free_thresh", 0.25))
    p = image.astype(np.float32) / 255.0 if negate else (255.0 - image.astype(np.float32)) / 255.0
    data = np.full(image.shape, -1, dtype=np.int8)
    data[p > occupied_at] = 100
    data[p < free_at] = 0
    return encode_map(np.flipud(data), resolution, (origin[0], origin[1]), f"learned map ({yaml_path.name})")


def _frame(
    run_dir: Path | None, name: Any, budget: list[int], cache: dict[str, str | None] | None
) -> str | None:
    """An event's picture as a small JPEG data URL, within the frame budget (``cache``: by name)."""
    if cache is not None and isinstance(name, str) and name in cache:
        found = cache[name]
        if found is not None and budget[0] < MAX_FRAMES and budget[1] + len(found) <= MAX_FRAME_BYTES:
            budget[0] += 1
            budget[1] += len(found)
            return found
        return None
    found = _encode_frame(run_dir, name, budget)
    if cache is not None and isinstance(name, str) and found is not None:
        cache[name] = found
    return found


def _encode_frame(run_dir: Path | None, name: Any, budget: list[int]) -> str | None:
    if run_dir is None or not isinstance(name, str) or budget[0] >= MAX_FRAMES:
        return None
    path = (run_dir / name).resolve()
    try:
        path.relative_to(run_dir.resolve())
    except ValueError:  # a path leaving the run directory is not ours to embed
        return None
    if not path.is_file():
        return None
    import cv2

    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        return None
    scale = min(1.0, 320.0 / max(image.shape[1], 1))
    if scale < 1.0:
        image = cv2.resize(
            image, (int(image.shape[1] * scale), int(image.shape[0] * scale)), interpolation=cv2.INTER_AREA
        )
    ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 75])
    if not ok or budget[1] + len(jpeg) > MAX_FRAME_BYTES:
        return None
    budget[0] += 1
    budget[1] += len(jpeg)
    return "data:image/jpeg;base64," + base64.b64encode(jpeg.tobytes()).decode("ascii")


def _finite_xy(value: Any) -> tuple[float, float] | None:
    """``value``'s first two numbers when both are finite, else None (a graph may hold anything)."""
    if not isinstance(value, list | tuple) or len(value) < 2:
        return None
    x, y = value[0], value[1]
    for v in (x, y):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            return None
    return round(float(x), 3), round(float(y), 3)


def _read_graph(run_dir: Path | None) -> dict[str, Any]:
    """The run's ``scene_graph.json`` as ``{"nodes": [...], "edges": [...]}`` (empty when absent)."""
    path = run_dir / "scene_graph.json" if run_dir is not None else None
    try:
        graph = json.loads(path.read_text(encoding="utf-8")) if path is not None and path.is_file() else {}
    except (OSError, ValueError):
        graph = {}
    if not isinstance(graph, dict):
        graph = {}
    return {key: [x for x in graph.get(key) or [] if isinstance(x, dict)]
            if isinstance(graph.get(key), list) else [] for key in ("nodes", "edges")}


def _served_object(summary: dict[str, Any]) -> str:
    """The id of the object the run's last served command went to ("" when none was served)."""
    outcome = summary.get("outcome")
    intent = outcome.get("intent") if isinstance(outcome, dict) else None
    commands = intent.get("commands") if isinstance(intent, dict) else None
    for record in reversed(commands if isinstance(commands, list) else []):
        if isinstance(record, dict) and record.get("status") == "served":
            return str(record.get("object", ""))
    return ""


def _room_centres(
    edges: list[dict[str, Any]], where: dict[str, tuple[float, float]], labels: dict[str, str]
) -> list[list[Any]]:
    """Each room at the centre of the objects it contains (the graph gives rooms no position).

    ``labels`` holds the rooms' labels by id (only rooms are placed).
    """
    members: dict[str, list[tuple[float, float]]] = {}
    for edge in edges:
        inside = str(edge.get("target_id"))[:40]
        if edge.get("relation") == "contains" and inside in where:
            members.setdefault(str(edge.get("source_id"))[:40], []).append(where[inside])
    centres = []
    for rid, points in members.items():
        if rid in labels:
            n = len(points)
            centres.append([round(sum(p[0] for p in points) / n, 3), round(sum(p[1] for p in points) / n, 3),
                            labels[rid]])
    return centres


def _finite(value: Any) -> float | None:
    """A finite number from untrusted JSON, else None."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


#: The run figures of summary.json's ``profile`` the page shows (the NAIS paper's Table III, per run).
PROFILE_RUN_KEYS = ("cpu_s", "wall_s", "robot_s", "realtime_factor", "cpu_realtime_factor", "rss_peak_mb",
                    "sim_cpu_s", "startup_cpu_s")


def profile_view(summary: dict[str, Any]) -> dict[str, Any] | None:
    """summary.json's ``profile`` for the page (None when the run has none).

    Per node ``[ticks, rate_hz, cpu_s]``, the run's figures and each model role's ``[calls, p50 ms,
    p95 ms]``; numbers that are not finite become null (the summary is read, not trusted).
    """
    profile = summary.get("profile")
    if not isinstance(profile, dict):
        return None
    nodes: dict[str, list[float | None]] = {}
    raw_nodes = profile.get("nodes")
    for path, row in (raw_nodes.items() if isinstance(raw_nodes, dict) else []):
        if isinstance(path, str) and isinstance(row, dict) and len(nodes) < MAX_SCENE_OBJECTS * 10:
            nodes[path[:300]] = [_finite(row.get(k)) for k in ("ticks", "rate_hz", "cpu_s")]
    run: dict[str, Any] = profile["run"] if isinstance(profile.get("run"), dict) else {}
    models: dict[str, list[float | None]] = {}
    raw_models = profile.get("models")
    for role, row in (raw_models.items() if isinstance(raw_models, dict) else []):
        if isinstance(role, str) and isinstance(row, dict) and len(models) < 100:
            models[role[:80]] = [_finite(row.get(k)) for k in ("calls", "latency_ms_p50", "latency_ms_p95")]
    return {"nodes": nodes, "run": {k: _finite(run.get(k)) for k in PROFILE_RUN_KEYS}, "models": models}


def scene_layer(run_dir: Path | None, summary: dict[str, Any], events: list[Any]) -> dict[str, Any] | None:
    """The scene graph as the map's layer: objects, rooms (at their objects' centre) and the target.

    Args:
        run_dir: The run directory (its ``scene_graph.json``, written at the end of mapping).
        summary: The run's summary.json (the intent outcome names the served object).
        events: The replayed events (a search's ``object_found`` says where the target was found).

    Returns:
        ``{"objects": [[x, y, label, id]], "rooms": [[x, y, label]], "target": [x, y, text] | None}``,
        or None when the run left neither a graph nor a found target.
    """
    graph = _read_graph(run_dir)
    objects: list[list[Any]] = []
    where: dict[str, tuple[float, float]] = {}
    labels: dict[str, str] = {}
    rooms: dict[str, str] = {}
    for node in graph["nodes"]:
        oid = str(node.get("id"))[:40]
        labels[oid] = str(node.get("label", ""))[:40]
        if node.get("type") == "room":
            rooms[oid] = labels[oid]
        xy = _finite_xy(node.get("coordinates")) if node.get("type") == "object" else None
        if xy is not None and len(objects) < MAX_SCENE_OBJECTS:
            where[oid] = xy
            objects.append([xy[0], xy[1], labels[oid], oid])
    target: list[Any] | None = None
    served = _served_object(summary)
    if served in where:
        target = [*where[served], f"served: {labels.get(served, served)}"]
    for event in events:
        xy = _finite_xy(event_position(event)) if event.kind in FOUND_EVENTS else None
        if xy is not None:
            target = [*xy, f"found: {str(event.fields.get('label', ''))[:40]}"]
    if not objects and target is None:
        return None
    return {"objects": objects, "rooms": _room_centres(graph["edges"], where, rooms), "target": target}


def page_data(
    replay: Replay, run_dir: Path | None = None, *, follow: bool = False,
    frame_cache: dict[str, str | None] | None = None,
) -> dict[str, Any]:
    """The viewer's data for one replayed run (JSON-ready, compact).

    Args:
        replay: The replayed run.
        run_dir: Its directory (run view, summary, alarm frames), or None.
        follow: The page polls for updates (``view --follow``).
        frame_cache: Encoded frames by name, kept between calls (the live server rebuilds often).
    """
    strings = _Strings()
    runview = read_runview(run_dir) if run_dir is not None else {}
    numbers = replay.tick_numbers
    consecutive = not numbers or numbers[-1] - numbers[0] == len(numbers) - 1
    arrays = _tick_arrays(replay, strings)  # strings first: their indices follow the order of calls
    events, frames = _events(replay, strings, run_dir, frame_cache)
    poses: list[float] = []
    for t, x, y in replay.poses:
        poses += [round(t, 3), round(x, 3), round(y, 3)]
    summary: dict[str, Any] = {}
    if run_dir is not None and (run_dir / "summary.json").is_file():
        try:
            summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError):
            summary = {}
        if not isinstance(summary, dict):  # a damaged summary is not a reason to lose the page
            summary = {}
    meta = _meta(replay, runview, summary, follow)
    return {
        "v": 1,
        "follow": follow,
        "lines": replay.lines,
        "meta": meta,
        "statuses": list(STATUSES),
        "categories": list(CATEGORIES),
        "s": strings.items,
        "nodes": arrays["nodes"],
        "first_tick": numbers[0] if numbers else 0,
        "tick_numbers": None if consecutive else numbers,
        "times": arrays["times"],
        "root": "".join(str(code) for code in replay.root_status),
        "changes": arrays["changes"],
        "bb": arrays["bb"],
        "events": events,
        "poses": poses,
        "map": _map_of(run_dir, runview),
        "frames": frames,
        "scene": scene_layer(run_dir, summary, replay.events),
        "profile": profile_view(summary),
        "ending": replay.ending(),
    }


def _meta(replay: Replay, runview: dict[str, Any], summary: dict[str, Any], follow: bool) -> dict[str, Any]:
    """The run as the page's header shows it: mission, status, how it stopped, rate, robot, seed."""
    finished = replay.finished
    status = finished.get("status") or (STATUSES[replay.root_status[-1]] if replay.root_status else "INVALID")
    meta = {
        "mission": replay.started.get("mission") or summary.get("mission") or "",
        "description": runview.get("description", ""),
        "mission_file": runview.get("mission_file", ""),
        "status": status,
        "stopped_by": finished.get("stopped_by", "" if follow else "unknown (no mission_finished line)"),
        "running": not finished,
        "tick_hz": replay.started.get("tick_hz") or summary.get("tick_hz") or 10.0,
        "robot": replay.started.get("robot", ""),
        "seed": replay.started.get("seed"),
        "declared": bool(runview.get("tree")) or any(n.type != "?" for n in replay.nodes),
    }
    return meta


def _tick_arrays(replay: Replay, strings: _Strings) -> dict[str, list[Any]]:
    """The tree's nodes, the status changes, the blackboard writes and the tick times, packed flat.

    Changes and writes give the tick as a step from the one before, times in milliseconds as steps;
    texts are indices into ``strings``. A node's conditions (``skip_if`` ..., from the log's
    ``conditions`` events) are shown with its parameters, as the mission file writes them.
    """
    conditions = node_conditions(replay)
    nodes = [
        [
            n.parent,
            strings(n.name),
            strings(n.type),
            strings(n.category),
            strings(_json({**n.params, **conditions.get(n.path, {})})),
            strings(n.source),
        ]
        for n in replay.nodes
    ]
    changes: list[int] = []
    previous = 0
    for change in replay.changes:
        changes += [
            change.tick - previous,
            change.node,
            change.status,
            strings(change.feedback),
            strings(change.reason),
        ]
        previous = change.tick
    board: list[int] = []
    previous = 0
    for at, key, value in replay.blackboard:
        board += [at - previous, strings(key), -1 if value is UNSET else strings(_json(value))]
        previous = at
    times: list[int] = []
    last_ms = 0
    for t in replay.times:
        ms = round(t * 1000)
        times.append(ms - last_ms)
        last_ms = ms
    return {"nodes": nodes, "times": times, "changes": changes, "bb": board}


def _events(
    replay: Replay, strings: _Strings, run_dir: Path | None, frame_cache: dict[str, str | None] | None,
) -> tuple[list[Any], dict[str, str]]:
    """The leaves' events packed flat, and the alarm and detection frames they name, encoded."""
    budget = [0, 0]
    events: list[Any] = []
    frames: dict[str, str] = {}
    for event in replay.events:
        category = event_category(event)
        where = event_position(event)
        image = event.fields.get("image")
        if category in ("alarm", "detection") and isinstance(image, str) and image not in frames:
            data_url = _frame(run_dir, image, budget, frame_cache)
            if data_url is not None:
                frames[image] = data_url
        events.append(
            [
                event.tick,
                strings(event.kind),
                CATEGORIES.index(category),
                strings(_json(event.fields)),
                None if where is None else round(where[0], 3),
                None if where is None else round(where[1], 3),
            ]
        )
    return events, frames


def _asset(name: str) -> str:
    return resources.files("missiontree.runlog").joinpath("assets", name).read_text(encoding="utf-8")


def render_page(data: dict[str, Any], title: str = "") -> str:
    """The whole HTML page with ``data`` inlined (``</`` escaped so the JSON cannot end the script)."""
    payload = json.dumps(data, separators=(",", ":"), ensure_ascii=False).replace("</", "<\\/")
    heading = title or f"missiontree run: {data['meta'].get('mission') or 'mission'}"
    escaped = heading.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{escaped}</title><style>{_asset('viewer.css')}</style></head>\n"
        f"<body>{_asset('viewer.html')}"
        f'<script type="application/json" id="mt-data">{payload}</script>\n'
        f"<script>{_asset('viewer.js')}</script></body></html>\n"
    )


def write_page(run: Path, out: Path | None = None, mission: Path | None = None) -> Path:
    """Build the viewer page of a run directory (or ticks.jsonl) and write it; return its path.

    Args:
        run: The run directory or its ticks.jsonl.
        out: Where to write (default: ``<run>/report.html``).
        mission: The mission file, when the run did not record its tree.
    """
    replay = open_run(run, mission)
    run_dir = Path(run) if Path(run).is_dir() else Path(run).parent
    page = render_page(page_data(replay, run_dir))
    target = Path(out) if out is not None else run_dir / "report.html"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(page, encoding="utf-8")
    return target
