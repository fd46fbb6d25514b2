// missiontree run viewer: replays the inlined tick data (see runlog/html.py for the encoding).
"use strict";
(function () {
  const KEY = 256;                       // keyframe every KEY ticks
  const $ = (id) => document.getElementById(id);
  let D, S, N, nodes, times, changes, chStart, bbAt, kf, cur = -1, selected = -1, shown = null, evIndex = [];
  let poses, mapImg = null, mapReady = false, playing = false, lastFrame = 0, carry = 0, matches = [], matchAt = -1;
  let rows = [], mapSize = null;

  function load(data) {
    D = data; S = D.s;
    nodes = D.nodes.map((n, i) => ({ id: i, parent: n[0], name: S[n[1]], type: S[n[2]], category: S[n[3]],
      params: S[n[4]], source: S[n[5]], kids: [] }));
    nodes.forEach((n) => { if (n.parent >= 0) nodes[n.parent].kids.push(n.id); });
    nodes.forEach((n) => { n.path = n.parent >= 0 ? nodes[n.parent].path + "/" + n.name : n.name; });
    N = D.times.length;
    times = new Float64Array(N);
    let ms = 0;
    for (let i = 0; i < N; i++) { ms += D.times[i]; times[i] = ms / 1000; }
    // changes: [dtick, node, status, feedback, reason] * n
    const c = D.changes, m = c.length / 5;
    changes = { tick: new Int32Array(m), node: new Int32Array(m), st: new Int8Array(m), fb: new Int32Array(m), rs: new Int32Array(m) };
    let t = 0;
    for (let j = 0; j < m; j++) {
      t += c[5 * j]; changes.tick[j] = t; changes.node[j] = c[5 * j + 1]; changes.st[j] = c[5 * j + 2];
      changes.fb[j] = c[5 * j + 3]; changes.rs[j] = c[5 * j + 4];
    }
    chStart = new Int32Array(N + 1);
    { let j = 0; for (let i = 0; i <= N; i++) { while (j < m && changes.tick[j] < i) j++; chStart[i] = j; } }
    const b = D.bb, bm = b.length / 3; bbAt = [];
    t = 0;
    for (let j = 0; j < bm; j++) { t += b[3 * j]; bbAt.push([t, S[b[3 * j + 1]], b[3 * j + 2]]); }
    // keyframes: kf[k] = state before tick k*KEY
    kf = [];
    const st = new Int8Array(nodes.length), fb = new Int32Array(nodes.length), rs = new Int32Array(nodes.length);
    let bb = new Map(), bj = 0;
    for (let k = 0; k * KEY <= Math.max(N - 1, 0); k++) {
      const end = k * KEY;
      if (k > 0) {
        for (let j = chStart[(k - 1) * KEY]; j < chStart[end]; j++) {
          const n = changes.node[j]; st[n] = changes.st[j]; fb[n] = changes.fb[j]; rs[n] = changes.rs[j];
        }
        while (bj < bbAt.length && bbAt[bj][0] < end) { applyBB(bb, bbAt[bj]); bj++; }
      }
      kf.push({ st: st.slice(), fb: fb.slice(), rs: rs.slice(), bb: new Map(bb), bj: bj });
    }
    poses = D.poses;
    evIndex = D.events.map((e, i) => i);
  }

  function applyBB(bb, e) { if (e[2] < 0) bb.delete(e[1]); else bb.set(e[1], e[2]); }

  // The state at the end of tick i: node statuses, feedback, reasons, blackboard.
  function stateAt(i) {
    const k = Math.floor((i + 1) / KEY), f = kf[Math.min(k, kf.length - 1)];
    const st = f.st.slice(), fb = f.fb.slice(), rs = f.rs.slice(), bb = new Map(f.bb);
    const from = Math.min(k, kf.length - 1) * KEY;
    for (let j = chStart[from]; j < chStart[Math.min(i + 1, N)]; j++) {
      const n = changes.node[j]; st[n] = changes.st[j]; fb[n] = changes.fb[j]; rs[n] = changes.rs[j];
    }
    let bj = f.bj, fresh = new Set();
    while (bj < bbAt.length && bbAt[bj][0] <= i) { applyBB(bb, bbAt[bj]); if (bbAt[bj][0] === i) fresh.add(bbAt[bj][1]); bj++; }
    return { st, fb, rs, bb, fresh };
  }

  // ---- tree -----------------------------------------------------------------------------------
  function paramText(p) {
    let o; try { o = JSON.parse(p); } catch (e) { return ""; }
    const parts = Object.keys(o).map((k) => k + "=" + (typeof o[k] === "object" ? JSON.stringify(o[k]) : o[k]));
    const text = parts.join(" ");
    return text.length > 90 ? text.slice(0, 87) + "…" : text;
  }

  function buildTree() {
    const root = $("tree"); root.textContent = ""; rows = new Array(nodes.length);
    const frag = document.createDocumentFragment();
    const make = (id, parentEl) => {
      const n = nodes[id], el = document.createElement("div");
      el.className = "node"; el.dataset.id = id; el.dataset.path = n.path; el.dataset.status = "INVALID";
      const row = document.createElement("div"); row.className = "row";
      row.innerHTML = '<span class="tog"></span><span class="dot"></span><span class="name"></span>' +
        '<span class="type"></span><span class="params"></span><span class="fb"></span>';
      row.children[0].textContent = n.kids.length ? "▾" : "";
      row.children[2].textContent = n.name;
      row.children[3].textContent = n.type === "?" ? "" : n.type;
      row.children[4].textContent = paramText(n.params);
      el.appendChild(row); rows[id] = el;
      if (n.kids.length) {
        const kids = document.createElement("div"); kids.className = "kids"; el.appendChild(kids);
        for (const k of n.kids) make(k, kids);
      }
      parentEl.appendChild(el);
    };
    nodes.forEach((n) => { if (n.parent < 0) make(n.id, frag); });
    root.appendChild(frag);
    $("treenote").textContent = nodes.length + " nodes" + (D.meta.declared ? "" : " (from the log: run with the mission file for types and parameters)");
    shown = null;
  }

  function toggle(id, open) {
    const el = rows[id]; if (!el || !nodes[id].kids.length) return;
    const closed = open === undefined ? !el.classList.contains("closed") : !open;
    el.classList.toggle("closed", closed);
    el.firstChild.firstChild.textContent = closed ? "▸" : "▾";
  }

  function reveal(id) { for (let p = nodes[id].parent; p >= 0; p = nodes[p].parent) toggle(p, true); }

  function select(id) {
    if (selected >= 0 && rows[selected]) rows[selected].classList.remove("sel");
    selected = id;
    if (id >= 0 && rows[id]) { rows[id].classList.add("sel"); reveal(id); }
    details();
  }

  // ---- panels ---------------------------------------------------------------------------------
  function details() {
    const box = $("details");
    if (selected < 0 || !shown) { box.className = "muted"; box.textContent = "click a node"; return; }
    const n = nodes[selected], s = shown, status = D.statuses[s.st[selected]];
    let last = -1, count = 0;
    for (let j = 0; j < chStart[Math.min(cur + 1, N)]; j++) if (changes.node[j] === selected) { last = j; count++; }
    const items = [["path", n.path], ["type", n.type + (n.category ? " (" + n.category + ")" : "")],
      ["status at this tick", status], ["feedback", S[s.fb[selected]] || "—"], ["failure reason", S[s.rs[selected]] || "—"],
      ["last change", last >= 0 ? "tick " + tickNumber(changes.tick[last]) + " (" + times[changes.tick[last]].toFixed(1) + " s)" : "never"],
      ["status changes so far", String(count)], ["parameters", n.params === "{}" ? "—" : n.params], ["declared at", n.source || "—"]];
    const prof = D.profile && D.profile.nodes[n.path];
    if (prof) items.push(["profile (whole run)", num(prof[0], 0) + " ticks · " + num(prof[1], 1) + " Hz · " + num(prof[2], 3) + " s CPU"]);
    box.className = ""; box.innerHTML = "<dl></dl>";
    const dl = box.firstChild;
    for (const [k, v] of items) {
      const dt = document.createElement("dt"), dd = document.createElement("dd");
      dt.textContent = k; dd.textContent = v; dd.dataset.field = k; dl.append(dt, dd);
    }
  }

  function num(v, digits) { return v === null || v === undefined ? "—" : Number(v).toFixed(digits); }

  // The run's profile (the NAIS paper's Table III): the run's figures and the nodes that took the most CPU.
  function profile() {
    const P = D.profile; $("profpane").hidden = !P; if (!P) return;
    const r = P.run;
    $("profnote").textContent = num(r.cpu_s, 2) + " s CPU · " + num(r.cpu_realtime_factor, 1) + "× real time (CPU) · " +
      num(r.rss_peak_mb, 0) + " MB peak";
    const rows = Object.entries(P.nodes).filter(([, v]) => v[2] !== null).sort((a, b) => b[1][2] - a[1][2]).slice(0, 12);
    const table = $("prof"); table.textContent = "";
    const head = document.createElement("tr"); head.innerHTML = "<th>node</th><th>Hz</th><th>ticks</th><th>CPU s</th>"; table.appendChild(head);
    for (const [path, v] of rows) {
      const tr = document.createElement("tr"); tr.dataset.path = path;
      for (const text of [path, num(v[1], 1), num(v[0], 0), num(v[2], 3)]) { const td = document.createElement("td"); td.textContent = text; tr.appendChild(td); }
      table.appendChild(tr);
    }
    for (const [role, v] of Object.entries(P.models)) {
      const tr = document.createElement("tr"); tr.className = "model";
      for (const text of ["model " + role, num(v[1], 0) + " ms p50", num(v[0], 0) + " calls", num(v[2], 0) + " ms p95"]) { const td = document.createElement("td"); td.textContent = text; tr.appendChild(td); }
      table.appendChild(tr);
    }
  }

  function blackboard(s) {
    const table = $("bb"); table.textContent = "";
    const keys = Array.from(s.bb.keys()).sort();
    for (const k of keys) {
      const tr = document.createElement("tr"), a = document.createElement("td"), b = document.createElement("td");
      a.textContent = k; b.textContent = S[s.bb.get(k)]; tr.dataset.key = k;
      if (s.fresh.has(k)) tr.className = "new";
      tr.append(a, b); table.appendChild(tr);
    }
    $("bbcount").textContent = keys.length + " keys";
  }

  function eventText(e) {
    let f; try { f = JSON.parse(S[e[3]]); } catch (x) { f = {}; }
    const node = f.node ? f.node + ": " : "";
    delete f.node;
    const first = ["verdict", "reason", "error", "id", "phase", "waypoint", "outcome"];
    const keys = Object.keys(f).filter((k) => k !== "image").sort((a, b) => (first.indexOf(a) + 1 || 99) - (first.indexOf(b) + 1 || 99));
    const parts = keys.map((k) => k + "=" + (typeof f[k] === "object" ? JSON.stringify(f[k]) : f[k]));
    const text = parts.join(" ");
    return node + (text.length > 160 ? text.slice(0, 157) + "…" : text);
  }

  function lastEventAtOrBefore(i) { // index into D.events of the last event with tick <= i
    let lo = 0, hi = D.events.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (D.events[mid][0] <= i) lo = mid + 1; else hi = mid; }
    return lo - 1;
  }

  function events(i) {
    const list = $("events"), filter = $("evfilter").value; list.textContent = "";
    const end = lastEventAtOrBefore(i);
    let shownCount = 0, total = 0;
    for (let j = end; j >= 0; j--) {
      const e = D.events[j];
      if (filter === "*key" ? e[2] === 2 || e[2] === 5 : filter && S[e[1]] !== filter) continue;
      total++;
      if (shownCount >= 100) continue;
      const li = document.createElement("li");
      li.className = "c" + e[2] + (e[0] === i ? " now" : ""); li.dataset.tick = tickNumber(e[0]); li.dataset.kind = S[e[1]];
      li.innerHTML = "<b></b> <span></span>";
      li.firstChild.textContent = times[e[0]].toFixed(1) + " s · " + S[e[1]];
      li.lastChild.textContent = eventText(e);
      li.onclick = () => { setTick(e[0]); showFrame(j); };
      list.appendChild(li); shownCount++;
    }
    $("evcount").textContent = total + " events" + (total > shownCount ? ", latest " + shownCount + " shown" : "");
    list.dataset.count = String(total);
  }

  // The frame sits beside the map: a run with frames keeps the column (a caption until the first
  // one) so that the map keeps its size and nothing covers it.
  function showFrame(j) {
    const box = $("frame"), was = box.hidden;
    placeFrame(j);
    if (box.hidden !== was) { mapSize = null; requestAnimationFrame(() => { if (cur >= 0) drawMap(cur); }); }  // the map's width changed
  }

  function placeFrame(j) {
    const box = $("frame"), reserved = Object.keys(D.frames || {}).length > 0;
    let f = {}; if (j >= 0) { try { f = JSON.parse(S[D.events[j][3]]); } catch (x) { f = {}; } }
    const url = f.image ? D.frames[f.image] : null;
    if (!url) {
      box.hidden = !reserved; $("frameimg").hidden = true; delete box.dataset.image;
      $("framecap").textContent = reserved ? "no alarm frame yet" : ""; return;
    }
    $("frameimg").hidden = false; $("frameimg").src = url; box.hidden = false; box.dataset.image = f.image;
    $("framecap").textContent = S[D.events[j][1]] + (f.id !== undefined ? " " + f.id : "") + " at " +
      times[D.events[j][0]].toFixed(1) + " s" + (f.verdict ? ": " + f.verdict : "");
  }

  // ---- map ------------------------------------------------------------------------------------
  function mapBounds() {
    let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
    const grow = (x, y) => { x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y); };
    if (D.map) { grow(D.map.origin[0], D.map.origin[1]); grow(D.map.origin[0] + D.map.width * D.map.resolution, D.map.origin[1] + D.map.height * D.map.resolution); }
    for (let j = 0; j < poses.length; j += 3) grow(poses[j + 1], poses[j + 2]);
    for (const e of D.events) if (e[4] !== null) grow(e[4], e[5]);
    if (D.scene) for (const o of D.scene.objects) grow(o[0], o[1]);
    if (!isFinite(x0)) { x0 = -5; y0 = -5; x1 = 5; y1 = 5; }
    const pad = 0.5; return [x0 - pad, y0 - pad, x1 + pad, y1 + pad];
  }

  function drawMap(i) {
    const cv = $("map");
    if (!mapSize) { const r = cv.getBoundingClientRect(); mapSize = [Math.max(200, Math.round(r.width)), Math.max(150, Math.round(r.height))]; }
    const [w, h] = mapSize;  // measured once (and on resize): reading layout each tick forces a reflow
    if (cv.width !== w || cv.height !== h) { cv.width = w; cv.height = h; }
    const g = cv.getContext("2d"); g.fillStyle = "#f4f4f4"; g.fillRect(0, 0, w, h);
    const [x0, y0, x1, y1] = mapBounds(), scale = Math.min(w / (x1 - x0), h / (y1 - y0));
    const ox = (w - (x1 - x0) * scale) / 2, oy = (h - (y1 - y0) * scale) / 2;
    const X = (x) => ox + (x - x0) * scale, Y = (y) => h - oy - (y - y0) * scale;
    if (D.map && mapReady) {
      g.imageSmoothingEnabled = false;
      g.drawImage(mapImg, X(D.map.origin[0]), Y(D.map.origin[1] + D.map.height * D.map.resolution),
        D.map.width * D.map.resolution * scale, D.map.height * D.map.resolution * scale);
    }
    const t = N ? times[i] : 0;
    // path up to the selected tick
    g.strokeStyle = "#2a6fdb"; g.lineWidth = 2; g.beginPath();
    let points = 0, rx = null, ry = null, lx = 0, ly = 0, drawn = 0;
    for (let j = 0; j < poses.length; j += 3) {
      if (poses[j] > t + 1e-9) break;
      const px = X(poses[j + 1]), py = Y(poses[j + 2]);
      if (points === 0) { g.moveTo(px, py); lx = px; ly = py; }
      else if (Math.abs(px - lx) + Math.abs(py - ly) >= 1.5) { g.lineTo(px, py); lx = px; ly = py; drawn++; }  // sub-pixel steps add nothing
      if (drawn === 400) { g.stroke(); g.beginPath(); g.moveTo(lx, ly); drawn = 0; }  // short paths stroke faster
      rx = poses[j + 1]; ry = poses[j + 2]; points++;
    }
    g.stroke();
    const counts = { goal: 0, alarm: 0, detection: 0 };
    const end = lastEventAtOrBefore(i);
    let lastGoal = -1;
    for (let j = 0; j <= end; j++) {
      const e = D.events[j]; if (e[4] === null) continue;
      const cat = D.categories[e[2]];
      if (cat === "goal") { counts.goal++; lastGoal = j; marker(g, X(e[4]), Y(e[5]), "#1f9d55", "circle", 4); }
      else if (cat === "alarm") {
        counts.alarm++; marker(g, X(e[4]), Y(e[5]), "#d93025", "triangle", 6);
        let f = {}; try { f = JSON.parse(S[e[3]]); } catch (x) { /* no fields */ }
        if (f.id !== undefined) { g.fillStyle = "#7a1010"; g.font = "10px sans-serif"; g.fillText(String(f.id), X(e[4]) + 7, Y(e[5]) - 4); }
      }
      else if (cat === "detection") { counts.detection++; marker(g, X(e[4]), Y(e[5]), "#e67e00", "square", 4); }
    }
    if (lastGoal >= 0) { const e = D.events[lastGoal]; g.strokeStyle = "#1f9d55"; g.lineWidth = 2; g.beginPath(); g.arc(X(e[4]), Y(e[5]), 8, 0, 7); g.stroke(); }
    const scene = drawScene(g, X, Y, scale);
    if (rx !== null) { marker(g, X(rx), Y(ry), "#0b3d91", "circle", 6); }
    // metre scale
    const m = Math.pow(10, Math.floor(Math.log10(80 / scale))) || 1;
    g.fillStyle = "#333"; g.fillRect(10, h - 14, m * scale, 3); g.font = "11px sans-serif"; g.fillText(m + " m", 14 + m * scale, h - 10);
    Object.assign(cv.dataset, { pathPoints: points, goals: counts.goal, alarms: counts.alarm, detections: counts.detection,
      robot: rx === null ? "" : rx.toFixed(2) + "," + ry.toFixed(2), ...scene });
    const a = lastAlarmWithFrame(i); showFrame(a);
  }

  // The scene graph the run left: objects with their labels, rooms at their objects' centre, and
  // the mission's target (the object served or found) ringed. Labels only where they fit.
  function drawScene(g, X, Y, scale) {
    const sc = D.scene, on = !!sc && $("scenetoggle").checked;
    if (!on) return { sceneObjects: 0, sceneRooms: 0, target: "" };
    const labels = scale >= 12;
    g.font = "10px sans-serif";
    for (const o of sc.objects) {
      const x = X(o[0]), y = Y(o[1]);
      g.fillStyle = "#6a3d9a"; g.beginPath(); g.moveTo(x, y - 4); g.lineTo(x + 4, y); g.lineTo(x, y + 4); g.lineTo(x - 4, y); g.closePath(); g.fill();
      if (labels) { g.fillStyle = "#3d2360"; g.fillText(o[2], x + 5, y + 3); }
    }
    g.font = "italic bold 12px sans-serif"; g.fillStyle = "rgba(40,40,40,0.75)";
    for (const r of sc.rooms) { const w = g.measureText(r[2]).width; g.fillText(r[2], X(r[0]) - w / 2, Y(r[1])); }
    const t = sc.target;
    if (t) {
      g.strokeStyle = "#c2185b"; g.lineWidth = 3; g.beginPath(); g.arc(X(t[0]), Y(t[1]), 10, 0, 7); g.stroke();
      g.font = "bold 11px sans-serif"; g.fillStyle = "#c2185b"; g.fillText(t[2], X(t[0]) + 12, Y(t[1]) - 8);
    }
    return { sceneObjects: sc.objects.length, sceneRooms: sc.rooms.length, target: t ? t[2] : "" };
  }

  function lastAlarmWithFrame(i) {
    for (let j = lastEventAtOrBefore(i); j >= 0; j--) {
      const e = D.events[j]; if (D.categories[e[2]] !== "alarm" && D.categories[e[2]] !== "detection") continue;
      try { const f = JSON.parse(S[e[3]]); if (f.image && D.frames[f.image]) return j; } catch (x) { /* no fields */ }
    }
    return -1;
  }

  function marker(g, x, y, colour, shape, r) {
    g.fillStyle = colour; g.beginPath();
    if (shape === "circle") g.arc(x, y, r, 0, 7);
    else if (shape === "square") g.rect(x - r, y - r, 2 * r, 2 * r);
    else { g.moveTo(x, y - r); g.lineTo(x + r, y + r); g.lineTo(x - r, y + r); g.closePath(); }
    g.fill();
  }

  // ---- timeline -------------------------------------------------------------------------------
  function tickNumber(i) { return D.tick_numbers ? D.tick_numbers[i] : D.first_tick + i; }

  function drawMarks() {
    const cv = $("marks"), w = Math.max(100, Math.round(cv.getBoundingClientRect().width));
    cv.width = w; const g = cv.getContext("2d"); g.clearRect(0, 0, w, 18);
    const colours = ["#1f9d55", "#d93025", "#7b4fd6", "#b3261e", "#e67e00", "#6b7280"];
    const x = (i) => N > 1 ? Math.round(i / (N - 1) * (w - 1)) : 0;
    for (const e of D.events) { if (e[2] === 5) continue; g.fillStyle = colours[e[2]]; g.fillRect(x(e[0]), e[2] === 2 ? 12 : 2, 1, e[2] === 2 ? 5 : 10); }
    g.fillStyle = colours[3];   // leaves turning FAILURE with a reason
    for (let j = 0; j < changes.st.length; j++) if (changes.st[j] === 3 && changes.rs[j] && !nodes[changes.node[j]].kids.length) g.fillRect(x(changes.tick[j]), 0, 2, 4);
  }

  function setTick(i) {
    if (!N) return;
    i = Math.max(0, Math.min(N - 1, Math.round(i)));
    const s = stateAt(i);
    for (let n = 0; n < nodes.length; n++) {
      if (shown && shown.st[n] === s.st[n] && shown.fb[n] === s.fb[n] && shown.rs[n] === s.rs[n]) continue;
      const el = rows[n]; if (!el) continue;
      el.dataset.status = D.statuses[s.st[n]];  // for tools and tests; styles key on the row's class
      el.firstChild.className = "row s" + s.st[n];
      el.firstChild.lastChild.textContent = s.st[n] ? (S[s.rs[n]] || S[s.fb[n]]) : "";
    }
    shown = s; cur = i;
    $("scrub").value = String(i);
    document.body.dataset.tick = String(tickNumber(i));
    document.body.dataset.index = String(i);
    $("clock").textContent = "tick " + tickNumber(i) + " / " + tickNumber(N - 1) + " · " + times[i].toFixed(1) + " s · root " + D.statuses[D.root.charCodeAt(i) - 48];
    blackboard(s); events(i); drawMap(i); details();
  }

  function play() {
    playing = !playing; $("play").innerHTML = playing ? "&#10074;&#10074;" : "&#9654;";
    if (playing) { if (cur >= N - 1) setTick(0); lastFrame = performance.now(); carry = 0; requestAnimationFrame(step); }
  }

  function step(now) {
    if (!playing) return;
    const dt = (now - lastFrame) / 1000; lastFrame = now;
    carry += dt * Number($("speed").value) * (D.meta.tick_hz || 10);
    const advance = Math.floor(carry);
    if (advance > 0) { carry -= advance; setTick(cur + advance); }
    if (cur >= N - 1) { play(); return; }
    requestAnimationFrame(step);
  }

  // ---- search and ending ----------------------------------------------------------------------
  function search() {
    const q = $("search").value.trim().toLowerCase();
    for (const id of matches) rows[id].classList.remove("match");
    matches = []; matchAt = -1;
    if (q) for (const n of nodes) if (n.name.toLowerCase().includes(q) || n.type.toLowerCase().includes(q)) matches.push(n.id);
    for (const id of matches) { rows[id].classList.add("match"); reveal(id); }
    $("matches").textContent = q ? matches.length + " match" + (matches.length === 1 ? "" : "es") : "";
  }

  function nextMatch() {
    if (!matches.length) return;
    matchAt = (matchAt + 1) % matches.length; const id = matches[matchAt];
    select(id); rows[id].scrollIntoView({ block: "center" });
  }

  function whyEnded() {
    const e = D.ending;
    for (const el of document.querySelectorAll(".node.chain")) el.classList.remove("chain");
    for (const id of e.chain) if (rows[id]) rows[id].classList.add("chain");
    const box = $("ending"); box.hidden = false; box.textContent = "Why it ended: " + e.text +
      (e.chain.length ? "  —  chain: " + e.chain.map((id) => nodes[id].name).join(" → ") : "");
    setTick(e.tick);
    if (e.chain.length) { select(e.chain[e.chain.length - 1]); rows[e.chain[e.chain.length - 1]].scrollIntoView({ block: "center" }); }
  }

  function header() {
    const m = D.meta;
    $("mission").textContent = m.mission || "mission";
    const badge = $("badge"); badge.textContent = m.running ? "RUNNING (live)" : m.status; badge.className = "badge " + (m.running ? "RUNNING" : m.status);
    $("summary").textContent = (m.stopped_by ? "stopped by " + m.stopped_by + " · " : "") + N + " ticks · " +
      (N ? times[N - 1].toFixed(1) : "0") + " s robot time" + (m.robot ? " · robot " + m.robot : "") + (m.seed !== null && m.seed !== undefined ? " · seed " + m.seed : "");
    $("mapnote").textContent = (D.map ? D.map.source : "no map recorded") + (D.scene ? " · scene graph at the end of the run" : "");
    $("scenekey").hidden = !D.scene;
    $("scrub").max = String(Math.max(N - 1, 0));
    const kinds = new Set(D.events.map((e) => S[e[1]])), sel = $("evfilter"), keep = sel.value;
    sel.innerHTML = '<option value="">all</option><option value="*key">goals, alarms, failures, detections</option>';
    for (const k of Array.from(kinds).sort()) { const o = document.createElement("option"); o.value = k; o.textContent = k; sel.appendChild(o); }
    sel.value = keep;
  }

  function loadMap() {
    mapReady = false;
    if (!D.map) return;
    mapImg = new Image();
    mapImg.onload = () => { mapReady = true; if (cur >= 0) drawMap(cur); };
    mapImg.src = "data:image/png;base64," + D.map.png;
  }

  function start(data) {
    load(data); header(); buildTree(); loadMap(); drawMarks();
    placeFrame(-1);  // reserve the frame's column before the map is measured
    profile();
    setTick(N - 1);
    if (D.meta.status === "FAILURE" && !D.meta.running) whyEnded();
  }

  // ---- live follow ----------------------------------------------------------------------------
  function follow() {
    setInterval(() => {
      fetch("data.json?lines=" + D.lines, { cache: "no-store" }).then((r) => r.ok ? r.json() : null).then((data) => {
        if (!data || data.lines === D.lines) return;
        const atEnd = cur >= N - 1, was = cur, count = nodes.length;
        load(data); header();
        if (nodes.length !== count) buildTree(); else shown = null;
        if (data.map && (!mapImg || !mapReady)) loadMap();
        drawMarks(); setTick(atEnd ? N - 1 : was);
      }).catch(() => { /* server gone: keep what we have */ });
    }, 1000);
  }

  // ---- wiring ---------------------------------------------------------------------------------
  $("tree").addEventListener("click", (ev) => {
    const el = ev.target.closest(".node"); if (!el) return;
    const id = Number(el.dataset.id);
    if (ev.target.classList.contains("tog")) toggle(id); else select(id);
  });
  $("scrub").addEventListener("input", (ev) => setTick(Number(ev.target.value)));
  $("play").addEventListener("click", play);
  $("why").addEventListener("click", whyEnded);
  $("search").addEventListener("input", search);
  $("search").addEventListener("keydown", (ev) => { if (ev.key === "Enter") nextMatch(); });
  $("evfilter").addEventListener("change", () => events(cur));
  $("scenetoggle").addEventListener("change", () => { if (cur >= 0) drawMap(cur); });
  $("expand").addEventListener("click", () => nodes.forEach((n) => toggle(n.id, true)));
  $("collapse").addEventListener("click", () => nodes.forEach((n) => toggle(n.id, n.parent < 0)));
  document.addEventListener("keydown", (ev) => {
    if (ev.target.tagName === "INPUT" && ev.target.type === "search") return;
    if (ev.key === " ") { ev.preventDefault(); play(); }
    else if (ev.key === "ArrowRight") setTick(cur + (ev.shiftKey ? 10 : 1));
    else if (ev.key === "ArrowLeft") setTick(cur - (ev.shiftKey ? 10 : 1));
  });
  window.addEventListener("resize", () => { mapSize = null; drawMarks(); if (cur >= 0) drawMap(cur); });

  start(JSON.parse($("mt-data").textContent));
  if (D.follow) follow();
  window.MT = { setTick, select, whyEnded, stateAt: (i) => { const s = stateAt(i); return { status: Array.from(s.st, (c) => D.statuses[c]), bb: Object.fromEntries(Array.from(s.bb, ([k, v]) => [k, S[v]])) }; },
    tick: () => cur, count: () => N, paths: () => nodes.map((n) => n.path), ready: true };
  document.body.dataset.ready = "1";
})();
