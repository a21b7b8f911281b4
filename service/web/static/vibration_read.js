/* The operation page's vibration read (templates/operation_vibration.html): this operation's
 * envelope against the breaker's fingerprint band, with the events marked. Data:
 * /ui/operations/<id>/vibration.json. Text is only ever set as textContent. */
(function () {
  "use strict";

  function $(sel) { return document.querySelector(sel); }

  function fmt(v, digits) {
    if (v === null || v === undefined || !isFinite(v)) { return "—"; }
    return Number(v).toPrecision(digits);
  }

  function markHook(list) {
    return function (u) {
      var ctx = u.ctx, top = u.bbox.top, h = u.bbox.height, px = window.devicePixelRatio || 1;
      ctx.save();
      list.forEach(function (m, i) {
        var x = Math.round(u.valToPos(m.t, "x", true));
        if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) { return; }
        ctx.strokeStyle = m.color;
        ctx.lineWidth = 1.5 * px;
        ctx.setLineDash([5 * px, 3 * px]);
        ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + h); ctx.stroke();
        ctx.setLineDash([]);
        ctx.fillStyle = m.color;
        ctx.font = (11 * px) + "px sans-serif";
        ctx.fillText(m.label, x + 3 * px, top + (12 + 12 * (i % 2)) * px);
      });
      ctx.restore();
    };
  }

  function draw(j) {
    var el = $('[data-chart="vibration-envelope"]');
    if (!el) { return; }
    if (!j.envelope) {
      el.textContent = j.reason ? "No envelope: " + j.reason : "No envelope: the vibration was not read.";
      return;
    }
    var t = j.envelope.t_ms;
    var series = [{ label: "time from the start of motion [ms]", value: function (u, v) { return v == null ? "—" : v.toFixed(2) + " ms"; } },
      { label: "this operation", stroke: "#1f5fa8", width: 1.5, points: { show: false },
        value: function (u, v) { return fmt(v, 3) + " g"; } }];
    var data = [t, j.envelope.g];
    var fp = j.fingerprint;
    if (fp && fp.mean_g) {
      series.push({ label: "fingerprint mean (" + fp.count + " healthy operations)", stroke: "#1b7f3b", width: 1.5, dash: [6, 3], points: { show: false },
        value: function (u, v) { return fmt(v, 3) + " g"; } });
      series.push({ label: "+3σ", stroke: "rgba(27,127,59,0.5)", width: 1, points: { show: false },
        value: function (u, v) { return fmt(v, 3) + " g"; } });
      series.push({ label: "−3σ", stroke: "rgba(27,127,59,0.5)", width: 1, points: { show: false },
        value: function (u, v) { return fmt(v, 3) + " g"; } });
      data.push(fp.mean_g, fp.hi_g, fp.lo_g);
    }
    var colors = { first_shock: "#b3261e", latch_release: "#d9822b", buffer_engagement: "#7a4cc2", end_stop: "#5d6d7e" };
    var marks = (j.events || []).filter(function (e) { return e.name !== "impact"; }).map(function (e) {
      return { t: e.t_s * 1e3, label: e.label, color: colors[e.name] || "#5d6d7e" };
    });
    marks.push({ t: 0, label: "motion", color: "#1b7f3b" });
    var opts = { width: Math.max(280, Math.floor(el.getBoundingClientRect().width || 400)), height: 220, series: series,
      scales: { x: { time: false }, y: { distr: 3 } },
      axes: [{ label: "time from the start of motion [ms]", labelSize: 18 }, { size: 60, label: "envelope [g]", labelSize: 16 }],
      hooks: { draw: [markHook(marks)] } };
    if (fp && fp.mean_g) { opts.bands = [{ series: [3, 4], fill: "rgba(27,127,59,0.08)" }]; }
    el.textContent = "";
    el.setAttribute("data-axis-labels", opts.axes.map(function (a) { return a.label; }).join("|"));
    new uPlot(opts, data, el);
    var note = $("#fingerprint-note");
    if (note) {
      if (!fp) {
        note.textContent = "No fingerprint yet: it is learnt from the breaker's first healthy operations of this kind (3 at least).";
      } else {
        var s = j.shift || {};
        var parts = ["Fingerprint from " + fp.count + " operations"];
        if (fp.latch) { parts.push("latch time " + fmt(fp.latch.mean_s * 1e3, 3) + " ± " + fmt(fp.latch.sd_s * 1e3, 2) + " ms"); }
        if (s.latch_shift_s !== null && s.latch_shift_s !== undefined) { parts.push("this operation " + (s.latch_shift_s >= 0 ? "+" : "") + fmt(s.latch_shift_s * 1e3, 3) + " ms (" + fmt(s.latch_z, 2) + " σ)"); }
        if (s.envelope_lag_s !== null && s.envelope_lag_s !== undefined) { parts.push("envelope shift " + fmt(s.envelope_lag_s * 1e3, 2) + " ms (correlation " + fmt(s.envelope_correlation, 2) + ")"); }
        if (s.strike_not_seen) { parts.push(s.strike_not_seen); }
        note.textContent = parts.join("; ") + ".";
      }
    }
  }

  document.addEventListener("DOMContentLoaded", function () {
    var box = $("#vibration-read");
    if (!box || !$('[data-chart="vibration-envelope"]')) { return; }
    fetch(box.getAttribute("data-vibration-url"), { credentials: "same-origin" })
      .then(function (r) { if (!r.ok) { throw new Error("vibration: HTTP " + r.status); } return r.json(); })
      .then(draw)
      .catch(function (e) { var el = $('[data-chart="vibration-envelope"]'); if (el) { el.textContent = String(e.message || e); } });
  });
}());
