// motecal view: draws the state document of motecal.view.state (live over
// Server-Sent Events from `motecal log --view`, or embedded by `motecal report`).
// Plain canvas 2D with a small orthographic 3D projection; no library, no build.
"use strict";
(function () {
  var state = null, selected = null, panels = {}, drawPending = false;
  var cam = { yaw: -0.6, pitch: 0.35 };          // spheres: drag to turn
  var BOARD_CAM = { yaw: -0.6, pitch: 0.45 };

  function $(id) { return document.getElementById(id); }
  function el(tag, attrs, html) {
    var e = document.createElement(tag);
    for (var k in attrs || {}) e.setAttribute(k, attrs[k]);
    if (html !== undefined) e.innerHTML = html;
    return e;
  }
  function pct(x) { return x == null ? "-" : (100 * x).toFixed(0) + "%"; }
  function fmt(x, d) { return x == null ? "-" : Number(x).toFixed(d || 0); }
  function setText(id, text, value) {
    var e = $(id); if (!e) return;
    if (e.textContent !== String(text)) e.textContent = text;
    if (value !== undefined) e.setAttribute("data-value", value);
  }

  // ---- vectors and projection ------------------------------------------------
  function norm(v) { return Math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }
  function unit(v) { var n = norm(v) || 1; return [v[0] / n, v[1] / n, v[2] / n]; }
  function cross(a, b) {
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  }
  function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  // world (x, y, z up) -> [screen x, screen y, depth]; camera looks from -y, above by pitch
  function project(p, c, cx, cy, s) {
    var cy_ = Math.cos(c.yaw), sy = Math.sin(c.yaw), cp = Math.cos(c.pitch), sp = Math.sin(c.pitch);
    var x1 = cy_ * p[0] - sy * p[1], y1 = sy * p[0] + cy_ * p[1], z1 = p[2];
    var up = sp * y1 + cp * z1, depth = cp * y1 - sp * z1;
    return [cx + s * x1, cy - s * up, depth];
  }
  // rotation board -> world for a gravity reading `g` (board frame, points up)
  // and a heading reference `ref` (board frame: the magnetometer, or a board axis)
  function frame(g, ref) {
    var up = unit(g);
    var e = cross(ref, up);
    if (norm(e) < 1e-3) e = cross(Math.abs(up[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0], up);
    var east = unit(e), north = cross(up, east);
    return [east, north, up];      // rows: world = R b
  }
  function apply(R, b) { return [dot(R[0], b), dot(R[1], b), dot(R[2], b)]; }
  function axisName(v) {
    var best = 0, name = "";
    [["+X", [1, 0, 0]], ["-X", [-1, 0, 0]], ["+Y", [0, 1, 0]], ["-Y", [0, -1, 0]],
     ["+Z", [0, 0, 1]], ["-Z", [0, 0, -1]]].forEach(function (a) {
      var d = dot(v, a[1]); if (d > best) { best = d; name = a[0]; }
    });
    return name;
  }

  // ---- drawing: the board ------------------------------------------------------
  var BOX = [1.0, 0.7, 0.09];      // half sizes: board x, y, thickness z
  var FACES = [  // [normal, name, colour]
    [[0, 0, 1], "+Z", "#3d8b4f"], [[0, 0, -1], "-Z", "#8a8f98"],
    [[1, 0, 0], "+X", "#c9c2a8"], [[-1, 0, 0], "-X", "#c9c2a8"],
    [[0, 1, 0], "+Y", "#bdb6a0"], [[0, -1, 0], "-Y", "#bdb6a0"]];
  function faceCorners(n) {
    var i = n[0] ? 0 : n[1] ? 1 : 2, j = (i + 1) % 3, k = (i + 2) % 3, out = [];
    [[-1, -1], [1, -1], [1, 1], [-1, 1]].forEach(function (s) {
      var p = [0, 0, 0]; p[i] = n[i] * BOX[i]; p[j] = s[0] * BOX[j]; p[k] = s[1] * BOX[k];
      out.push(p);
    });
    return out;
  }
  function drawBoard(cv, g, ref, opts) {
    var ctx = cv.getContext("2d"), W = cv.width, H = cv.height, cx = W / 2, cy = H / 2 + 10;
    var s = Math.min(W, H) * 0.36;
    ctx.clearRect(0, 0, W, H);
    // ground and the vertical
    ctx.strokeStyle = "#ccc"; ctx.lineWidth = 1;
    ctx.beginPath();
    for (var a = 0; a <= 64; a++) {
      var t = a / 64 * 2 * Math.PI, q = project([1.3 * Math.cos(t), 1.3 * Math.sin(t), -0.9], BOARD_CAM, cx, cy, s);
      a ? ctx.lineTo(q[0], q[1]) : ctx.moveTo(q[0], q[1]);
    }
    ctx.stroke();
    if (opts.ring != null) {           // capture progress ring
      var r = Math.min(W, H) * 0.46;
      ctx.lineWidth = 7; ctx.strokeStyle = "#e4e4e4";
      ctx.beginPath(); ctx.arc(cx, cy - 10, r, 0, 2 * Math.PI); ctx.stroke();
      ctx.strokeStyle = opts.ringColour;
      ctx.beginPath(); ctx.arc(cx, cy - 10, r, -Math.PI / 2, -Math.PI / 2 + 2 * Math.PI * opts.ring);
      ctx.stroke();
    }
    if (!g) {
      ctx.fillStyle = "#888"; ctx.font = "13px sans-serif"; ctx.textAlign = "center";
      ctx.fillText(opts.empty || "no data", cx, cy); return;
    }
    var R = frame(g, ref || [1, 0, 0]);
    var cam3 = BOARD_CAM;
    if (opts.faceUp) {              // turn the camera to the side the up face is tilted to
      var best = FACES[0][0];
      FACES.forEach(function (f) { if (dot(f[0], unit(g)) > dot(best, unit(g))) best = f[0]; });
      var nW = apply(R, best);
      if (Math.hypot(nW[0], nW[1]) > 0.05)
        cam3 = { yaw: -Math.PI / 2 + 0.6 - Math.atan2(nW[1], nW[0]), pitch: BOARD_CAM.pitch };
    }
    var faces = FACES.map(function (f) {
      var pts = faceCorners(f[0]).map(function (p) { return project(apply(R, p), cam3, cx, cy, s); });
      var nW = apply(R, f[0]), nS = project(nW, cam3, 0, 0, 1);
      var depth = pts.reduce(function (a, p) { return a + p[2]; }, 0) / 4;
      return { f: f, pts: pts, facing: nS[2] < 0, depth: depth };
    }).filter(function (x) { return x.facing; });
    faces.sort(function (a, b) { return b.depth - a.depth; });
    faces.forEach(function (x) {
      ctx.beginPath();
      x.pts.forEach(function (p, i) { i ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1]); });
      ctx.closePath();
      ctx.globalAlpha = opts.ghost ? 0.55 : 1;
      ctx.fillStyle = x.f[2]; ctx.fill();
      ctx.globalAlpha = 1; ctx.strokeStyle = "#333"; ctx.lineWidth = 1; ctx.stroke();
      if (x.f[1] === "+Z" || x.f[1] === "-Z") {
        var c = x.pts.reduce(function (a, p) { return [a[0] + p[0] / 4, a[1] + p[1] / 4]; }, [0, 0]);
        ctx.fillStyle = "#fff"; ctx.font = "bold 13px sans-serif"; ctx.textAlign = "center";
        ctx.fillText(x.f[1], c[0], c[1] + 4);
      }
    });
    // the board's +X (red) and +Y (green) axes from its centre, over the top
    [[[1.35, 0, 0], "#d03030", "X"], [[0, 1.05, 0], "#208030", "Y"], [[0, 0, 0.6], "#3050d0", "Z"]].forEach(function (a) {
      var o = project([0, 0, 0], cam3, cx, cy, s), e = project(apply(R, a[0]), cam3, cx, cy, s);
      ctx.strokeStyle = a[1]; ctx.lineWidth = 2; ctx.beginPath();
      ctx.moveTo(o[0], o[1]); ctx.lineTo(e[0], e[1]); ctx.stroke();
      ctx.fillStyle = a[1]; ctx.font = "11px sans-serif"; ctx.fillText(a[2], e[0] + 4, e[1]);
    });
    ctx.fillStyle = "#222"; ctx.font = "12px sans-serif"; ctx.textAlign = "left";
    var u = unit(g), tilt = Math.acos(Math.max(-1, Math.min(1, Math.max(Math.abs(u[0]), Math.abs(u[1]), Math.abs(u[2]))))) * 180 / Math.PI;
    ctx.fillText(axisName(u) + " up, tilt " + tilt.toFixed(0) + "\u00b0", 6, H - 6);
  }

  // ---- drawing: spheres ----------------------------------------------------------
  function sphereFrame(ctx, W, H, s, cx, cy, cells) {
    ctx.clearRect(0, 0, W, H);
    ctx.strokeStyle = "#999"; ctx.lineWidth = 1;
    if (!(cells && cells.bare)) { ctx.beginPath(); ctx.arc(cx, cy, s, 0, 2 * Math.PI); ctx.stroke(); }
    ctx.strokeStyle = "#e2e2e2";
    var b, k, t;
    var bands = cells ? cells.bands : 6, sectors = cells ? cells.sectors : 12;
    for (b = 1; b < bands; b++) {             // equal-area band borders (z = const)
      var z = 1 - 2 * b / bands, r = Math.sqrt(1 - z * z);
      ctx.beginPath();
      for (k = 0; k <= 48; k++) {
        t = k / 48 * 2 * Math.PI;
        var q = project([r * Math.cos(t), r * Math.sin(t), z], cam, cx, cy, s);
        k ? ctx.lineTo(q[0], q[1]) : ctx.moveTo(q[0], q[1]);
      }
      ctx.stroke();
    }
    for (k = 0; k < sectors; k++) {           // sector borders (meridians)
      var az = -Math.PI + k / sectors * 2 * Math.PI;
      ctx.beginPath();
      for (b = 0; b <= 24; b++) {
        var zz = 1 - 2 * b / 24, rr = Math.sqrt(Math.max(0, 1 - zz * zz));
        var p = project([rr * Math.cos(az), rr * Math.sin(az), zz], cam, cx, cy, s);
        b ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1]);
      }
      ctx.stroke();
    }
    [[[1.25, 0, 0], "#d03030", "+X"], [[0, 1.25, 0], "#208030", "+Y"], [[0, 0, 1.25], "#3050d0", "+Z"]].forEach(function (a) {
      var o = project([0, 0, 0], cam, cx, cy, s), e = project(a[0], cam, cx, cy, s);
      ctx.strokeStyle = a[1]; ctx.beginPath(); ctx.moveTo(o[0], o[1]); ctx.lineTo(e[0], e[1]); ctx.stroke();
      ctx.fillStyle = a[1]; ctx.font = "11px sans-serif"; ctx.fillText(a[2], e[0] + 2, e[1]);
    });
  }
  function dotAt(ctx, v, cx, cy, s, r, colour, ring) {
    var p = project(v, cam, cx, cy, s), back = p[2] > 0;
    ctx.globalAlpha = back ? 0.3 : 1;
    ctx.beginPath(); ctx.arc(p[0], p[1], r, 0, 2 * Math.PI);
    if (ring) { ctx.strokeStyle = colour; ctx.lineWidth = 2.5; ctx.stroke(); }
    else { ctx.fillStyle = colour; ctx.fill(); }
    ctx.globalAlpha = 1;
  }
  function cellCentre(b, k, bands, sectors) {
    var z = 1 - (b + 0.5) * 2 / bands, r = Math.sqrt(1 - z * z);
    var az = -Math.PI + (k + 0.5) * 2 * Math.PI / sectors;
    return [r * Math.cos(az), r * Math.sin(az), z];
  }
  function cellOf(v, bands, sectors) {
    var u = unit(v);
    var b = Math.min(bands - 1, Math.max(0, Math.floor((1 - u[2]) / 2 * bands)));
    var k = Math.min(sectors - 1, Math.max(0, Math.floor((Math.atan2(u[1], u[0]) + Math.PI) / (2 * Math.PI) * sectors)));
    return b * sectors + k;
  }
  function drawGravity(cv, st, live) {
    var ctx = cv.getContext("2d"), W = cv.width, H = cv.height, s = Math.min(W, H) * 0.38;
    var cx = W / 2, cy = H / 2;
    sphereFrame(ctx, W, H, s, cx, cy, { bands: st.bands, sectors: st.sectors });
    st.targets.forEach(function (t) { dotAt(ctx, t, cx, cy, s, 2.2, "#9aa0a8"); });
    st.accepted.forEach(function (a) { dotAt(ctx, a, cx, cy, s, 4, "#2a9a3a"); });
    if (st.target) dotAt(ctx, st.target, cx, cy, s, 8, "#f08c00", true);
    if (live) dotAt(ctx, unit(live), cx, cy, s, 5, "#d02020");
  }
  function drawPoints(cv, sw, fitted) {
    var ctx = cv.getContext("2d"), W = cv.width, H = cv.height, s = Math.min(W, H) * 0.38;
    var cx = W / 2, cy = H / 2, c = sw.centre, i, p;
    if (fitted) {
      sphereFrame(ctx, W, H, s, cx, cy, sw);
      var R = sw.radius || 1;
      for (i = 0; i < sw.hits.length; i++) {      // the gaps: cells without a point
        if (sw.hits[i]) continue;
        var q = project(cellCentre(Math.floor(i / sw.sectors), i % sw.sectors, sw.bands, sw.sectors), cam, cx, cy, s);
        ctx.globalAlpha = q[2] > 0 ? 0.25 : 0.9;
        ctx.strokeStyle = "#d02020"; ctx.lineWidth = 2; ctx.beginPath();
        ctx.moveTo(q[0] - 4, q[1] - 4); ctx.lineTo(q[0] + 4, q[1] + 4);
        ctx.moveTo(q[0] + 4, q[1] - 4); ctx.lineTo(q[0] - 4, q[1] + 4); ctx.stroke();
      }
      ctx.globalAlpha = 1;
      for (i = 0; i < sw.points.length; i++) {
        p = sw.points[i];
        dotAt(ctx, [(p[0] - c[0]) / R, (p[1] - c[1]) / R, (p[2] - c[2]) / R], cx, cy, s, 1.6, "#1f6fd0");
      }
    } else {                                    // raw counts: the offset shows
      var m = 1;
      sw.points.forEach(function (q) { m = Math.max(m, norm(q)); });
      sphereFrame(ctx, W, H, s, cx, cy, { bands: 1, sectors: 0, bare: true });
      for (i = 0; i < sw.points.length; i++) {
        p = sw.points[i];
        dotAt(ctx, [p[0] / m, p[1] / m, p[2] / m], cx, cy, s, 1.6, "#7a4fc0");
      }
      dotAt(ctx, [c[0] / m, c[1] / m, c[2] / m], cx, cy, s, 5, "#f08c00", true);
      ctx.fillStyle = "#555"; ctx.font = "11px sans-serif"; ctx.textAlign = "left";
      ctx.fillText("centre " + c.map(function (x) { return x.toFixed(0); }).join(", ") + " counts", 4, H - 5);
    }
  }
  function drawGrid(cv, hits, bands, sectors, mark) {
    var ctx = cv.getContext("2d"), W = cv.width, H = cv.height;
    var cw = (W - 2) / sectors, ch = (H - 14) / bands;
    ctx.clearRect(0, 0, W, H);
    for (var b = 0; b < bands; b++) for (var k = 0; k < sectors; k++) {
      var i = b * sectors + k;
      ctx.fillStyle = hits[i] ? "#2a9a3a" : "#f3d6d2";
      ctx.fillRect(1 + k * cw, 1 + b * ch, cw - 1, ch - 1);
      if (i === mark) { ctx.strokeStyle = "#f08c00"; ctx.lineWidth = 3; ctx.strokeRect(2 + k * cw, 2 + b * ch, cw - 3, ch - 3); }
    }
    ctx.fillStyle = "#555"; ctx.font = "10px sans-serif"; ctx.textAlign = "left";
    ctx.fillText("+Z band on top; azimuth -180\u00b0 \u2192 180\u00b0", 1, H - 2);
  }


  // ---- the report's calibration part (drawn by charts.js) ------------------------
  function calibrationPart(P, groups) {
    var box = el("div", { "class": "calib", id: P + "calib" });
    box.appendChild(el("h2", {}, "the calibration (as in the report's sections)"));
    var k = 0;
    groups.forEach(function (g) {
      box.appendChild(el("h3", { "class": "calibhead" }, g.heading.replace(/</g, "&lt;")));
      var r = el("div", { "class": "row" });
      g.charts.forEach(function (ch) {
        var bars = ch.series.filter(function (s) { return s.kind === "barh"; })[0];
        var wide = g.charts.length === 1;
        var c = el("div", { "class": "card" });
        var w = wide ? 760 : 285;
        var cv = el("canvas", { id: P + "chart" + k, "class": "chart", "data-title": ch.title,
                                width: w, height: bars ? 36 + 20 * bars.values.length : 200 });
        c.appendChild(cv);
        c.appendChild(el("div", { "class": "legend", style: "max-width:" + w + "px" },
                         window.motecalCharts.legend(ch)));
        r.appendChild(c);
        window.motecalCharts.draw(cv, ch);
        k++;
      });
      box.appendChild(r);
    });
    return box;
  }

  // ---- the page ----------------------------------------------------------------
  function card(title, id, w, h) {
    var c = el("div", { "class": "card" });
    c.appendChild(el("h3", {}, title));
    c.appendChild(el("canvas", { id: id, width: w, height: h }));
    return c;
  }
  function panel(m) {
    var id = m.id, P = "m" + id + "-";
    var d = el("div", { "class": "mote", id: P + "panel", "data-mote": id });
    var st = el("div", { "class": "static", id: P + "static" });
    st.appendChild(el("div", { "class": "guide" },
      'pose <b id="' + P + 'pose">-</b> of <span id="' + P + 'poses">-</span> &mdash; ' +
      '<span id="' + P + 'phase"></span><br><span id="' + P + 'target"></span>'));
    st.appendChild(el("div", { "class": "warn", id: P + "warning" }));
    var r = el("div", { "class": "row" });
    var tc = card("take this pose", P + "board-target", 250, 210);
    var slider = el("input", { type: "range", id: P + "posepick", min: 1, max: 80, value: 80 });
    slider.oninput = function () { schedule(); };
    var sl = el("div", { "class": "legend", id: P + "pickrow" });
    sl.appendChild(slider);
    sl.appendChild(el("span", { id: P + "pickname" }));
    tc.appendChild(sl);
    r.appendChild(tc);
    r.appendChild(card("the board now (accelerometer, magnetometer heading)", P + "board-live", 250, 210));
    r.appendChild(card("gravity directions (drag to turn)", P + "gravity", 250, 250));
    var g = card("coverage cells (4 x 5)", P + "grid", 170, 120);
    g.appendChild(el("div", { "class": "legend" },
      '<span class="dot" style="background:#2a9a3a"></span> taken ' +
      '<span class="dot" style="background:#9aa0a8"></span> suggested ' +
      '<span class="dot" style="border:2px solid #f08c00;width:6px;height:6px"></span> next ' +
      '<span class="dot" style="background:#d02020"></span> now'));
    r.appendChild(g);
    st.appendChild(r);
    st.appendChild(el("div", { "class": "numbers" },
      '<span>poses taken <b id="' + P + 'accepted">0</b></span>' +
      '<span>coverage <b id="' + P + 'coverage">-</b></span>' +
      '<span>still <b id="' + P + 'still">-</b></span>' +
      '<span>capture <b id="' + P + 'captured">-</b></span>' +
      '<span>discarded (moved) <b id="' + P + 'discards">-</b></span>'));
    d.appendChild(st);
    var sw = el("div", { "class": "sweep", id: P + "sweep" });
    sw.appendChild(el("div", { "class": "guide" },
      'sweep &mdash; <span id="' + P + 'sphase"></span>: <b id="' + P + 'scount">0</b> of <span id="' + P + 'ssamples">-</span> samples'));
    var r2 = el("div", { "class": "row" });
    r2.appendChild(card("magnetometer, raw counts", P + "raw", 280, 260));
    r2.appendChild(card("as fitted so far (x = gap)", P + "fitted", 280, 260));
    r2.appendChild(card("coverage cells (10 x 10)", P + "sgrid", 200, 170));
    sw.appendChild(r2);
    sw.appendChild(el("div", { "class": "numbers" },
      '<span>points <b id="' + P + 'points">0</b></span>' +
      '<span>coverage <b id="' + P + 'scoverage">-</b></span>' +
      '<span>gaps <b id="' + P + 'gaps">-</b></span>' +
      '<span>fit error <b id="' + P + 'fiterror">-</b></span>' +
      '<span>radius <b id="' + P + 'radius">-</b> counts</span>'));
    d.appendChild(sw);
    if (m.calibration && m.calibration.length) d.appendChild(calibrationPart(P, m.calibration));
    var lv = el("div", { "class": "liveonly", id: P + "liveonly" });
    lv.appendChild(card("the board now", P + "board-only", 250, 210));
    d.appendChild(lv);
    $("motes").appendChild(d);
    var b = el("button", { id: P + "tab", "data-mote": id }, "mote " + id);
    b.onclick = function () { selected = id; schedule(); };
    $("tabs").appendChild(b);
    ["gravity", "raw", "fitted"].forEach(function (n) { dragTurn($(P + n)); });
    return d;
  }
  function dragTurn(cv) {
    var last = null;
    cv.addEventListener("mousedown", function (e) { last = [e.clientX, e.clientY]; });
    window.addEventListener("mouseup", function () { last = null; });
    window.addEventListener("mousemove", function (e) {
      if (!last) return;
      cam.yaw += (e.clientX - last[0]) * 0.01;
      cam.pitch = Math.max(-1.5, Math.min(1.5, cam.pitch + (e.clientY - last[1]) * 0.01));
      last = [e.clientX, e.clientY]; schedule();
    });
  }

  function update(doc) {
    state = doc;
    setText("session", doc.session || "");
    var conn = $("conn");
    var mode = doc.mode === "static" ? "stored" : doc.ended ? "ended" : doc.connected ? "live" : "lost";
    conn.className = "badge " + mode;
    conn.textContent = { stored: "stored session", ended: "session ended (" + doc.stop_reason + ")",
                         live: "live", lost: "port lost: reconnecting" }[mode];
    setText("flow", doc.flow ? doc.flow : "unguided");
    setText("source", doc.source || "");
    setText("elapsed", doc.elapsed == null ? "" : fmt(doc.elapsed, 0) + " s");
    var ln = doc.line || {};
    setText("line", "line: frames " + (ln.frames || 0) + ", CRC errors " + (ln.crc_errors || 0) +
      ", garbage bytes " + (ln.garbage_bytes || 0) + ", disconnects " + (ln.disconnects || 0));
    var tb = document.querySelector("#links tbody");
    doc.motes.forEach(function (m) {
      var P = "m" + m.id + "-";
      if (!panels[m.id]) {
        panels[m.id] = panel(m);
        var tr = el("tr", { id: P + "link" });
        ["id", "state", "samples", "rate", "lost", "duplicates", "reordered", "mote_dropped", "temp_c", "guide"].forEach(function (k) {
          tr.appendChild(el("td", { id: P + k }));
        });
        tb.appendChild(tr);
        if (selected === null) selected = m.id;
      }
      var c = m.link || {};
      setText(P + "id", m.id);
      setText(P + "state", m.state); $(P + "state").className = m.state;
      setText(P + "samples", c.samples == null ? "-" : c.samples, c.samples);
      setText(P + "rate", c.rate == null ? "-" : fmt(c.rate, 0), c.rate);
      ["lost", "duplicates", "reordered", "mote_dropped"].forEach(function (k) {
        setText(P + k, c[k] == null ? "-" : c[k], c[k]);
      });
      setText(P + "temp_c", c.temp_c == null ? "-" : fmt(c.temp_c, 1) + " C", c.temp_c);
      var guide = m.static ? "pose " + m.static.pose + "/" + m.static.poses + ", " + pct(m.static.coverage)
        : m.sweep ? "sweep " + pct(m.sweep.coverage) : "";
      setText(P + "guide", guide);
      var st = m.static, sw = m.sweep;
      $(P + "static").style.display = st ? "" : "none";
      $(P + "sweep").style.display = sw ? "" : "none";
      $(P + "liveonly").style.display = (st || sw) ? "none" : "";
      if (st) {
        setText(P + "pose", st.pose, st.pose);
        setText(P + "poses", st.poses);
        setText(P + "phase", st.phase);
        setText(P + "target", st.target_text ? "suggested: " + st.target_text : "");
        var warn = st.warning || "";
        if (!warn && st.captured === 0) {        // the last capture of this pose was discarded
          (doc.events || []).forEach(function (e) {
            if (e.mote === m.id && e.pose === st.pose && e.kind === "discarded") warn = e.text;
          });
        }
        setText(P + "warning", warn);
        setText(P + "accepted", st.accepted.length, st.accepted.length);
        setText(P + "coverage", pct(st.coverage), st.coverage);
        setText(P + "still", doc.mode === "static" ? "-" : st.still ? "yes" : "no");
        setText(P + "captured", st.captured + " / " + st.samples, st.captured);
        setText(P + "discards", st.discards == null ? "-" : st.discards);
      }
      if (sw) {
        setText(P + "sphase", sw.phase);
        setText(P + "scount", sw.samples_seen, sw.samples_seen);
        setText(P + "ssamples", sw.samples);
        setText(P + "points", sw.count, sw.count);
        setText(P + "scoverage", pct(sw.coverage), sw.coverage);
        setText(P + "gaps", pct(1 - sw.coverage));
        setText(P + "fiterror", sw.fit_error == null ? "-" : fmt(sw.fit_error, 1) + "%", sw.fit_error);
        setText(P + "radius", fmt(sw.radius, 0));
      }
    });
    var ul = $("events"), html = "";
    (doc.events || []).slice().reverse().forEach(function (e) {
      html += '<li class="' + e.kind + '">' + (e.t == null ? "" : fmt(e.t, 1) + " s  ") +
        e.text.replace(/&/g, "&amp;").replace(/</g, "&lt;") + "</li>";
    });
    if (ul.innerHTML !== html) ul.innerHTML = html;
    schedule();
  }

  function schedule() {
    if (drawPending) return;
    drawPending = true;
    (window.requestAnimationFrame || setTimeout)(draw);
  }
  function draw() {
    drawPending = false;
    if (!state) return;
    state.motes.forEach(function (m) {
      var P = "m" + m.id + "-", on = m.id === selected;
      $(P + "panel").style.display = on ? "" : "none";
      $(P + "tab").className = on ? "on" : "";
      if (!on) return;
      var acc = m.live && m.live.acc, mag = m.live && m.live.mag;
      if (mag && !(norm(mag) > 0)) mag = null;
      var st = m.static, sw = m.sweep;
      if (st) {
        // the pose shown: the next suggested one, or (stored) the last taken
        var tgt = st.target, stored = state.mode === "static";
        $(P + "pickrow").style.display = stored && st.accepted.length ? "" : "none";
        if (stored && st.accepted.length) {          // a stored session: any pose taken
          var pick = $(P + "posepick");
          pick.max = st.accepted.length;
          var k = Math.min(Number(pick.value), st.accepted.length);
          tgt = st.accepted[k - 1];
          setText(P + "pickname", " pose " + (st.labels ? st.labels[k - 1] : k) + " as taken");
          $(P + "board-target").previousSibling.textContent = "a pose taken (slide to choose)";
        }
        var ref = [1, 0, 0];
        if (acc && mag) ref = frame(acc, mag)[1];     // the live board's north, board frame
        drawBoard($(P + "board-target"), tgt, ref, { ghost: true, faceUp: true, empty: "all poses taken" });
        var ring = null, colour = "#2a9a3a";
        if (state.mode === "live" && !st.done) {
          ring = st.captured / st.samples;
          if (!st.still) colour = "#e08a00";
          if (st.still && st.captured === 0) ring = 1, colour = "#9ccf9f";
        }
        $(P + "board-live").parentNode.style.display = stored ? "none" : "";
        drawBoard($(P + "board-live"), acc, mag || [1, 0, 0],
                  { ring: ring, ringColour: colour, empty: state.mode === "static" ? "stored session: no live data" : "waiting for samples" });
        drawGravity($(P + "gravity"), st, acc);
        drawGrid($(P + "grid"), st.hits, st.bands, st.sectors,
                 st.target ? cellOf(st.target, st.bands, st.sectors) : -1);
      }
      if (sw) {
        drawPoints($(P + "raw"), sw, false);
        drawPoints($(P + "fitted"), sw, true);
        drawGrid($(P + "sgrid"), sw.hits, sw.bands, sw.sectors, -1);
      }
      if (!st && !sw) drawBoard($(P + "board-only"), acc, mag || [1, 0, 0], { empty: "waiting for samples" });
    });
  }

  // ---- where the state comes from --------------------------------------------------
  if (window.MOTECAL_STATE) {                   // a report: the data is in the page
    update(window.MOTECAL_STATE);
  } else if (window.EventSource) {
    var es = new EventSource("events");
    es.addEventListener("state", function (e) {
      var doc = JSON.parse(e.data);
      update(doc);
      if (doc.ended) es.close();                // the logger is gone: nothing more comes
    });
    es.onerror = function () {
      if (state && state.ended) return;
      var c = $("conn"); c.className = "badge lost"; c.textContent = "view disconnected: retrying";
    };
  }
  window.motecalView = { state: function () { return state; } };
})();
