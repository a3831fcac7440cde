// motecal view: the charts of the report's calibration part (motecal.report.charts:
// one description of a plot, drawn by matplotlib into the report's PNGs and here on a
// canvas).  Plain canvas 2D, no library; view.js calls window.motecalCharts.
"use strict";
(function () {
  function niceTicks(lo, hi, n) {
    var span = hi - lo;
    if (!(span > 0)) return [lo];
    var raw = span / n, mag = Math.pow(10, Math.floor(Math.log10(raw))), f = raw / mag;
    var step = (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10) * mag, out = [];
    for (var t = Math.ceil(lo / step) * step; t <= hi + 1e-9 * span; t += step)
      out.push(Math.abs(t) < 1e-9 * step ? 0 : t);
    return out;
  }
  function tickText(v) {
    var a = Math.abs(v);
    return a !== 0 && (a < 1e-3 || a >= 1e5) ? v.toExponential(1) : String(Number(v.toPrecision(4)));
  }
  function chartRange(ch) {
    var x = [Infinity, -Infinity], y = [Infinity, -Infinity];
    function ax(r, v) { if (v != null && isFinite(v)) { r[0] = Math.min(r[0], v); r[1] = Math.max(r[1], v); } }
    ch.series.forEach(function (s) {
      if (s.kind === "points" || s.kind === "line") { s.x.forEach(function (v) { ax(x, v); }); s.y.forEach(function (v) { ax(y, v); }); }
      else if (s.kind === "band") { s.x.forEach(function (v) { ax(x, v); }); s.lo.forEach(function (v) { ax(y, v); }); s.hi.forEach(function (v) { ax(y, v); }); }
      else if (s.kind === "hline") ax(y, s.y);
      else if (s.kind === "vline") ax(x, s.x);
      else if (s.kind === "barh") { ax(x, 0); s.values.forEach(function (v) { ax(x, v); }); }
    });
    if (ch.xlim) x = ch.xlim.slice();
    [x, y].forEach(function (r) {
      if (!isFinite(r[0])) { r[0] = 0; r[1] = 1; }
      if (r[1] - r[0] < 1e-12) { r[0] -= 0.5; r[1] += 0.5; }
    });
    var pad = 0.06 * (y[1] - y[0]);
    if (!ch.ylog) { y[0] -= pad; y[1] += pad; }
    return { x: x, y: y };
  }
  function drawChart(cv, ch) {
    var ctx = cv.getContext("2d"), W = cv.width, H = cv.height;
    var bars = ch.series.filter(function (s) { return s.kind === "barh"; })[0];
    var L = bars ? 8 : 56, R = 10, T = 20, B = 32;
    var r = chartRange(ch), ylog = !!ch.ylog && r.y[0] > 0;
    var fy = ylog ? function (v) { return Math.log10(v); } : function (v) { return v; };
    var y0 = fy(r.y[0]), y1 = fy(r.y[1]);
    function X(v) { return L + (v - r.x[0]) / (r.x[1] - r.x[0]) * (W - L - R); }
    function Y(v) { return T + (1 - (fy(v) - y0) / (y1 - y0)) * (H - T - B); }
    ctx.clearRect(0, 0, W, H);
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, W, H);
    ctx.save(); ctx.beginPath(); ctx.rect(L, T, W - L - R, H - T - B); ctx.clip();
    function poly(xs, ys) {
      var open = false;
      ctx.beginPath();
      for (var i = 0; i < xs.length; i++) {
        if (xs[i] == null || ys[i] == null || (ylog && ys[i] <= 0)) { open = false; continue; }
        open ? ctx.lineTo(X(xs[i]), Y(ys[i])) : ctx.moveTo(X(xs[i]), Y(ys[i]));
        open = true;
      }
    }
    var order = ["vspan", "hspan", "band", "hline", "vline", "line", "points", "barh"];
    order.forEach(function (kind) {
      ch.series.forEach(function (s) {
        if (s.kind !== kind) return;
        ctx.strokeStyle = ctx.fillStyle = s.colour || "#222";
        ctx.setLineDash(s.dash ? [5, 4] : []);
        ctx.lineWidth = s.width || 1;
        if (kind === "vspan") { ctx.globalAlpha = 0.18; ctx.fillRect(X(s.x0), T, X(s.x1) - X(s.x0), H - T - B); }
        else if (kind === "hspan") { ctx.globalAlpha = 0.18; ctx.fillRect(L, Y(s.y1), W - L - R, Y(s.y0) - Y(s.y1)); }
        else if (kind === "band") {
          ctx.globalAlpha = 0.25; ctx.beginPath();
          for (var i = 0; i < s.x.length; i++) i ? ctx.lineTo(X(s.x[i]), Y(s.hi[i])) : ctx.moveTo(X(s.x[i]), Y(s.hi[i]));
          for (var j = s.x.length - 1; j >= 0; j--) ctx.lineTo(X(s.x[j]), Y(s.lo[j]));
          ctx.closePath(); ctx.fill();
        }
        else if (kind === "hline") { ctx.beginPath(); ctx.moveTo(L, Y(s.y)); ctx.lineTo(W - R, Y(s.y)); ctx.stroke(); }
        else if (kind === "vline") { ctx.beginPath(); ctx.moveTo(X(s.x), T); ctx.lineTo(X(s.x), H - B); ctx.stroke(); }
        else if (kind === "line") { poly(s.x, s.y); ctx.stroke(); }
        else if (kind === "points") {
          var rad = Math.max(1.2, (s.size || 3) * 0.55);
          for (var k = 0; k < s.x.length; k++) {
            if (s.x[k] == null || s.y[k] == null || (ylog && s.y[k] <= 0)) continue;
            ctx.beginPath(); ctx.arc(X(s.x[k]), Y(s.y[k]), rad, 0, 2 * Math.PI); ctx.fill();
          }
        }
        else if (kind === "barh") {
          var n = s.values.length, h = (H - T - B) / n;
          for (var b = 0; b < n; b++) {
            ctx.globalAlpha = 0.85; ctx.fillStyle = s.colours[b];
            ctx.fillRect(X(0), T + b * h + 2, X(s.values[b]) - X(0), h - 4);
            ctx.globalAlpha = 1; ctx.fillStyle = "#111"; ctx.font = "10px sans-serif"; ctx.textAlign = "left";
            ctx.fillText(s.labels[b], X(0) + 3, T + b * h + h / 2 + 3);
          }
        }
        ctx.globalAlpha = 1; ctx.setLineDash([]);
      });
    });
    ctx.restore();
    // axes, ticks and labels
    ctx.strokeStyle = "#888"; ctx.lineWidth = 1; ctx.strokeRect(L, T, W - L - R, H - T - B);
    ctx.fillStyle = "#333"; ctx.font = "10px sans-serif"; ctx.textAlign = "center";
    niceTicks(r.x[0], r.x[1], 5).forEach(function (t) {
      if (!ch.xint || Math.round(t) === t) ctx.fillText(tickText(t), X(t), H - B + 12);
    });
    ctx.fillText(ch.xlabel || "", L + (W - L - R) / 2, H - 5);
    if (!bars) {
      ctx.textAlign = "right";
      var yt = niceTicks(r.y[0], r.y[1], 5);
      if (ylog) {                                  // decades, else a few values in between
        yt = [];
        for (var e = Math.ceil(y0); e <= Math.floor(y1); e++) yt.push(Math.pow(10, e));
        if (yt.length < 2) yt = niceTicks(y0, y1, 4).map(function (t) { return Math.pow(10, t); });
      }
      yt.forEach(function (t) { ctx.fillText(tickText(t), L - 3, Y(t) + 3); });
      ctx.save(); ctx.translate(11, T + (H - T - B) / 2); ctx.rotate(-Math.PI / 2); ctx.textAlign = "center";
      ctx.fillText(ch.ylabel || "", 0, 0); ctx.restore();
    }
    ctx.textAlign = "left"; ctx.font = "bold 11px sans-serif"; ctx.fillStyle = "#222";
    ctx.fillText(ch.title || "", 4, 13);
  }
  function chartLegend(ch) {
    var seen = {}, html = "";
    ch.series.forEach(function (s) {
      if (!s.label || seen[s.label]) return;
      seen[s.label] = 1;
      html += '<span class="dot" style="background:' + s.colour + '"></span> ' +
        s.label.replace(/&/g, "&amp;").replace(/</g, "&lt;") + " ";
    });
    return html;
  }
  window.motecalCharts = { draw: drawChart, legend: chartLegend };
})();
