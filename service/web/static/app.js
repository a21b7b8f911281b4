/* hvcb web page: charts (uPlot) and live updates. No framework, no build step.
 * Data comes as JSON from /ui/... on this origin; stored text is only ever set as textContent
 * or arrives in server-rendered (escaped) HTML fragments. */
(function () {
  "use strict";

  var body = document.body;
  var charts = {};
  window.hvcb = { charts: charts };  // for the browser tests and bench/ui_speed.py
  var COLORS = { line: "#1f5fa8", band: "rgba(31,95,168,0.16)", bandEdge: "rgba(31,95,168,0.35)",
    fit: "#d9822b", base: "#1b7f3b", warn: "#d59b00", alarm: "#b3261e", vib: "#5d6d7e",
    vibBand: "rgba(93,109,126,0.35)", open: "#1f5fa8", close: "#7a4cc2" };

  function $(sel, root) { return (root || document).querySelector(sel); }
  function $$(sel, root) { return Array.prototype.slice.call((root || document).querySelectorAll(sel)); }

  // -- dialogs (baseline reset confirmation) ---------------------------------------------------
  document.addEventListener("click", function (ev) {
    var opener = ev.target.closest("[data-open-dialog]");
    if (opener) {
      var d = document.getElementById(opener.getAttribute("data-open-dialog"));
      if (d && d.showModal) { d.showModal(); }
      return;
    }
    var closer = ev.target.closest("[data-close-dialog]");
    if (closer) { var dlg = closer.closest("dialog"); if (dlg) { dlg.close(); } }
  });

  // -- chart helpers ---------------------------------------------------------------------------
  function widthOf(el) { return Math.max(280, Math.floor(el.getBoundingClientRect().width || 400)); }

  // uPlot draws axis titles on its canvas: the container names them too, for assistive tools and tests
  function axisLabels(el, opts) {
    el.setAttribute("data-axis-labels", (opts.axes || []).map(function (a) { return a.label || ""; }).join("|"));
  }

  function draw(key, el, opts, data) {
    var old = charts[key];
    if (old && old.root.parentNode === el) {
      old.setData(data);
      return old;
    }
    if (old) { old.destroy(); }
    el.textContent = "";
    opts.width = widthOf(el);
    var u = new uPlot(opts, data, el);
    axisLabels(el, opts);
    charts[key] = u;
    return u;
  }

  function markerHook(marks) {
    // vertical lines at alarm times, coloured by level
    return function (u) {
      var ctx = u.ctx, top = u.bbox.top, h = u.bbox.height;
      ctx.save();
      marks.forEach(function (m) {
        var x = Math.round(u.valToPos(m.t, "x", true));
        if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) { return; }
        ctx.strokeStyle = m.level === "alarm" ? COLORS.alarm : COLORS.warn;
        ctx.lineWidth = 2 * devicePixelRatio;
        ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + h); ctx.stroke();
        ctx.fillStyle = ctx.strokeStyle;
        ctx.beginPath(); ctx.moveTo(x - 5 * devicePixelRatio, top); ctx.lineTo(x + 5 * devicePixelRatio, top);
        ctx.lineTo(x, top + 8 * devicePixelRatio); ctx.closePath(); ctx.fill();
      });
      ctx.restore();
    };
  }

  function spansHook(spans, labels) {
    // shaded x-ranges (phases, fit window) behind the series
    return function (u) {
      var ctx = u.ctx, top = u.bbox.top, h = u.bbox.height;
      ctx.save();
      spans.forEach(function (s, i) {
        var x0 = u.valToPos(s.t0, "x", true), x1 = u.valToPos(s.t1, "x", true);
        ctx.fillStyle = s.fill || (i % 2 ? "rgba(31,95,168,0.07)" : "rgba(217,130,43,0.09)");
        ctx.fillRect(x0, top, x1 - x0, h);
        if (labels && s.name) {
          ctx.fillStyle = "#4a5868";
          ctx.font = (11 * devicePixelRatio) + "px system-ui, sans-serif";
          ctx.textAlign = "center";
          ctx.fillText(s.name.replace(/_/g, " "), (x0 + x1) / 2, top + 13 * devicePixelRatio);
        }
      });
      ctx.restore();
    };
  }

  function pad2(n) { return (n < 10 ? "0" : "") + n; }

  function utcTicks(u, splits) {
    // UTC, 24 h: the page states every time in UTC
    var span = splits.length > 1 ? splits[splits.length - 1] - splits[0] : 0;
    return splits.map(function (v) {
      if (v == null) { return ""; }
      var d = new Date(v * 1000);
      var hm = pad2(d.getUTCHours()) + ":" + pad2(d.getUTCMinutes());
      var md = d.getUTCFullYear() + "-" + pad2(d.getUTCMonth() + 1) + "-" + pad2(d.getUTCDate());
      if (span > 3 * 86400) { return md; }
      if (span > 86400) { return md.slice(5) + " " + hm; }
      return span < 600 ? hm + ":" + pad2(d.getUTCSeconds()) : hm;
    });
  }

  var TIME_AXIS = { values: utcTicks, space: 70, label: "time (UTC)", labelSize: 16 };
  // a dimensionless parameter (BC, an inertia ratio) is labelled as what it is
  function unitWord(unit) { return !unit || unit === "–" || unit === "-" ? "ratio" : unit; }
  var UTC = function (ts) { return uPlot.tzDate(new Date(ts * 1000), "Etc/UTC"); };

  function hideLegendEntries(u, labels) {
    // legend rows that only repeat another (a band's lower edge, the time column)
    Array.prototype.forEach.call(u.root.querySelectorAll(".u-legend .u-series"), function (row) {
      var label = row.querySelector(".u-label");
      if (label && labels.indexOf(label.textContent) >= 0) { row.style.display = "none"; }
    });
  }

  function constant(arr, v) { return arr.map(function () { return v; }); }

  function fmt(v, digits) {
    if (v === null || v === undefined || !isFinite(v)) { return "—"; }
    return Number(v).toPrecision(digits || 5);
  }

  // -- breaker page ----------------------------------------------------------------------------
  function paramChart(name, p) {
    var box = $('[data-param="' + name + '"]');
    if (!box) { return; }
    var el = $(".chart", box);
    if (!p || !p.t.length) { box.classList.add("empty"); return; }
    box.classList.remove("empty");
    var series = [{},
      { label: name, stroke: COLORS.line, width: 1.5, points: { show: p.t.length < 120, size: 4 },
        value: function (u, v) { return fmt(v, 5) + " " + unitWord(p.unit); } },
      { label: "95 % CI", stroke: COLORS.bandEdge, width: 0.5, points: { show: false } },
      { label: "95 % CI (lower)", stroke: COLORS.bandEdge, width: 0.5, points: { show: false } }];
    var data = [p.t, p.value, p.hi, p.lo];
    if (p.drift && p.drift.baseline) {
      series.push({ label: "baseline mean", stroke: COLORS.base, width: 1.5, dash: [6, 4], points: { show: false } });
      data.push(constant(p.t, p.drift.baseline.mean));
    }
    var opts = { height: 190, series: series, legend: { live: false }, tzDate: UTC,
      scales: { x: { time: true } },
      axes: [TIME_AXIS, { size: 64, label: name + " [" + unitWord(p.unit) + "]", labelSize: 16 }],
      bands: [{ series: [2, 3], fill: COLORS.band }],
      cursor: { sync: { key: "breaker" } },
      hooks: { draw: [markerHook(p.alarms || [])] } };
    var u = draw("param-" + name, el, opts, data);
    hideLegendEntries(u, ["Time", "95 % CI (lower)"]);
    note(box, p);
  }

  function driftChart(name, p) {
    var box = $('[data-drift="' + name + '"]');
    if (!box) { return; }
    var el = $(".chart", box);
    var d = p && p.drift;
    if (!d || !d.t.length || !d.baseline) {
      box.classList.add("empty");
      var note = d ? ("baseline: " + d.collected + " of " + d.baseline_n + " good fits") : "no data yet";
      el.textContent = note;
      return;
    }
    box.classList.remove("empty");
    var opts = { height: 190, legend: { live: false }, tzDate: UTC,
      series: [{},
        { label: "CUSUM", stroke: "#38424f", width: 1.6, spanGaps: false, points: { show: false },
          fill: "rgba(56,66,79,0.06)" },
        { label: "warning " + fmt(d.warning, 3) + " σ", stroke: COLORS.warn, width: 1.4, dash: [6, 4], points: { show: false } },
        { label: "alarm " + fmt(d.alarm, 3) + " σ", stroke: COLORS.alarm, width: 1.4, dash: [6, 4], points: { show: false } }],
      scales: { x: { time: true }, y: { range: function (u, lo, hi) { return [0, Math.max(hi, d.alarm * 1.25)]; } } },
      axes: [TIME_AXIS, { size: 64, label: "CUSUM [σ]", labelSize: 16 }],
      cursor: { sync: { key: "breaker" } },
      hooks: { draw: [markerHook(p.alarms || [])] } };
    var u = draw("drift-" + name, el, opts, [d.t, d.s, constant(d.t, d.warning), constant(d.t, d.alarm)]);
    hideLegendEntries(u, ["Time"]);
  }

  function charChart(key, label, unit, chars) {
    var box = $('[data-char="' + key + '"]');
    if (!box) { return; }
    var el = $(".chart", box);
    var tables = [], series = [{}], per = chars[key] || {};
    ["open", "close"].forEach(function (kind) {
      var c = per[kind];
      if (c && c.t.length) {
        tables.push([c.t, c.v]);
        series.push({ label: kind === "open" ? "opening" : "closing", stroke: COLORS[kind], width: 1.4,
          spanGaps: true, points: { show: c.t.length < 120, size: 4 } });
      }
    });
    if (!tables.length) { box.classList.add("empty"); return; }
    box.classList.remove("empty");
    var data = tables.length === 1 ? tables[0] : uPlot.join(tables);
    var opts = { height: 170, series: series, scales: { x: { time: true } }, legend: { live: false }, tzDate: UTC,
      axes: [TIME_AXIS, { size: 64, label: label + " [" + unit + "]", labelSize: 16 }], cursor: { sync: { key: "breaker" } } };
    var u = draw("char-" + key, el, opts, data);
    hideLegendEntries(u, ["Time"]);
  }

  function note(box, p) {
    // say when a long history is drawn decimated
    var n = $(".chart-note", box);
    if (!n) { n = document.createElement("div"); n.className = "chart-note small muted"; box.appendChild(n); }
    n.textContent = p.n > p.shown ? p.n.toLocaleString("en") + " fits, drawn as the min/max of " +
      Math.round(p.shown / 2).toLocaleString("en") + " groups" : "";
  }

  function loadTrends() {
    var url = body.getAttribute("data-trends-url");
    return fetch(url, { headers: { Accept: "application/json" }, cache: "no-store", credentials: "same-origin" })
      .then(function (r) { if (!r.ok) { throw new Error("trends: HTTP " + r.status); } return r.json(); })
      .then(function (j) {
        $$("[data-param]").forEach(function (box) {
          var name = box.getAttribute("data-param");
          paramChart(name, j.params[name]);
        });
        $$("[data-drift]").forEach(function (box) {
          var name = box.getAttribute("data-drift");
          driftChart(name, j.params[name]);
        });
        j.characteristic_labels.forEach(function (c) { charChart(c[0], c[1], c[2], j.characteristics); });
      });
  }

  // -- operation page --------------------------------------------------------------------------
  var curvesFor = null;

  function loadCurves() {
    var url = body.getAttribute("data-curves-url");
    var status = ($("#op-summary") || body).getAttribute("data-fit-status");
    curvesFor = status;
    return fetch(url, { headers: { Accept: "application/json" }, cache: "no-store", credentials: "same-origin" })
      .then(function (r) {
        if (r.status === 410) { return r.json().then(function (j) { $("#curve-note").textContent = j.detail; return null; }); }
        if (!r.ok) { throw new Error("curves: HTTP " + r.status); }
        return r.json();
      })
      .then(function (j) { if (j) { drawOperation(j); if (j.note) { $("#curve-note").textContent = j.note; } } });
  }

  function blockMean(y, n) {
    // the systematic part of the residual: the noise averages out over n samples
    var out = new Array(y.length).fill(null);
    for (var i = 0; i < y.length; i += n) {
      var s = 0, k = 0;
      for (var m = i; m < Math.min(i + n, y.length); m++) { if (y[m] !== null) { s += y[m]; k++; } }
      if (k === n) { for (m = i; m < i + n; m++) { out[m] = s / k; } }
    }
    return out;
  }

  function drawOperation(j) {
    var tms = j.t.map(function (v) { return v * 1e3; });
    var sync = { key: "op" };
    var spans = (j.phases || []).map(function (p) { return { t0: p.t0 * 1e3, t1: p.t1 * 1e3, name: p.name }; });
    var windowSpan = j.window ? [{ t0: j.window[0] * 1e3, t1: j.window[1] * 1e3, fill: "rgba(27,127,59,0.06)" }] : [];

    var tSeries = [{ label: "t [ms]", value: function (u, v) { return v == null ? "—" : v.toFixed(3) + " ms"; } },
      { label: "measured", stroke: COLORS.line, width: 1.2, points: { show: false },
        value: function (u, v) { return fmt(v, 5) + " rad"; } }];
    var tData = [tms, j.measured];
    if (j.fitted) {
      tSeries.push({ label: "fitted model", stroke: COLORS.fit, width: 2, points: { show: false },
        value: function (u, v) { return fmt(v, 5) + " rad"; } });
      tData.push(j.fitted);
    }
    draw("travel", $('[data-chart="travel"]'), { height: 300, series: tSeries, scales: { x: { time: false } },
      axes: [{ label: "time [ms]", labelSize: 18 }, { size: 60, label: "travel [rad]", labelSize: 16 }],
      cursor: { sync: sync }, hooks: { drawClear: [spansHook(windowSpan, false)] } }, tData);

    var resEl = $('[data-chart="residual"]');
    if (j.residual) {
      var two = 2 * (j.noise || 0) * 1e3;
      var r = j.residual.map(function (v) { return v === null ? null : v * 1e3; });
      var has = r.map(function (v) { return v === null ? null : 0; });
      var mean = blockMean(r, Math.max(1, Math.round(j.sample_rate * 2.5e-4)));
      draw("residual", resEl, { height: 200,
        series: [{ label: "t [ms]", value: function (u, v) { return v == null ? "—" : v.toFixed(3) + " ms"; } },
          { label: "residual", stroke: "rgba(80,92,106,0.55)", width: 1, points: { show: false },
            value: function (u, v) { return fmt(v, 3) + " mrad"; } },
          { label: "±2σ band: " + (j.noise_basis === "residual in motion" ? "the residual's own noise in motion" : "the noise before the motion"), stroke: "#b3261e", width: 2, dash: [8, 4], points: { show: false },
            value: function (u, v) { return v == null ? "—" : "±" + fmt(v, 3) + " mrad"; } },
          { label: "−2σ", stroke: "#b3261e", width: 2, dash: [8, 4], points: { show: false } },
          { label: "mean of 0.25 ms blocks", stroke: "#d9822b", width: 2, points: { show: false },
            value: function (u, v) { return fmt(v, 3) + " mrad"; } }],
        bands: [{ series: [2, 3], fill: "rgba(179,38,30,0.06)" }],
        scales: { x: { time: false } },
        axes: [{ label: "time [ms]", labelSize: 18 }, { size: 60, label: "residual [mrad]", labelSize: 16 }],
        cursor: { sync: sync }, hooks: { drawClear: [spansHook(spans, true)] } },
        [tms, r, has.map(function (v) { return v === null ? null : two; }), has.map(function (v) { return v === null ? null : -two; }), mean]);
      hideLegendEntries(charts.residual, ["−2σ"]);
    } else {
      resEl.textContent = "The residual appears when the fit is done.";
      if (charts.residual) { charts.residual.destroy(); delete charts.residual; }
    }

    var vEl = $('[data-chart="vibration"]');
    if (j.vibration) {
      var vt = j.vibration.t.map(function (v) { return v * 1e3; });
      draw("vibration", vEl, { height: 180,
        series: [{ label: "t [ms]", value: function (u, v) { return v == null ? "—" : v.toFixed(3) + " ms"; } },
          { label: "max", stroke: COLORS.vib, width: 1, points: { show: false },
            value: function (u, v) { return v == null ? "—" : fmt(v, 3) + " g"; } },
          { label: "min", stroke: COLORS.vib, width: 1, points: { show: false },
            value: function (u, v) { return v == null ? "—" : fmt(v, 3) + " g"; } }],
        bands: [{ series: [1, 2], fill: COLORS.vibBand }],
        scales: { x: { time: false } },
        axes: [{ label: "time [ms]", labelSize: 18 }, { size: 60, label: "vibration [g]", labelSize: 16 }],
        cursor: { sync: sync } }, [vt, j.vibration.max, j.vibration.min]);
    } else {
      vEl.textContent = "This capture has no vibration channel.";
    }
    $("#curve-note").textContent = j.samples + " samples at " + (j.sample_rate / 1000).toFixed(0) +
      " kHz, travel drawn at full resolution" + (j.vibration ? "; vibration as min/max of " + j.vibration.buckets + " buckets" : "") + ".";
  }

  // -- page loaders ----------------------------------------------------------------------------
  function loadPage() {
    var kind = body.getAttribute("data-page");
    var p = Promise.resolve();
    if (kind === "breaker") { p = loadTrends(); }
    if (kind === "operation") { p = loadCurves(); }
    return p;
  }

  function refreshPage() {
    var kind = body.getAttribute("data-page");
    if (kind === "breaker") { return loadTrends(); }
    if (kind === "operation") {
      var status = ($("#op-summary") || body).getAttribute("data-fit-status");
      if (status !== curvesFor) { return loadCurves(); }
    }
    return Promise.resolve();
  }

  // -- live updates: poll a change marker; on change, swap the page's live parts -------------
  var marker = body.getAttribute("data-marker");
  var pollMs = Math.max(500, 1000 * parseFloat(body.getAttribute("data-poll-s") || "3"));
  var liveEl = $("#live-state");

  function setLive(ok, why) {
    if (!liveEl) { return; }
    liveEl.classList.toggle("off", !ok);
    liveEl.textContent = ok ? "live" : (why || "offline");
  }

  function busy(el) {
    var a = document.activeElement;
    return el.querySelector("dialog[open]") || (a && el.contains(a) && (a.tagName === "INPUT" || a.tagName === "SELECT"));
  }

  function swapLive() {
    return fetch(location.href, { headers: { Accept: "text/html" }, cache: "no-store", credentials: "same-origin" })
      .then(function (r) { if (!r.ok) { throw new Error("page: HTTP " + r.status); } return r.text(); })
      .then(function (html) {
        var doc = new DOMParser().parseFromString(html, "text/html");
        $$("[data-live][id]").forEach(function (el) {
          var fresh = doc.getElementById(el.id);
          if (!fresh || busy(el) || fresh.innerHTML === el.innerHTML) { return; }
          el.innerHTML = fresh.innerHTML;
          Array.prototype.forEach.call(fresh.attributes, function (a) {
            if (a.name.indexOf("data-") === 0) { el.setAttribute(a.name, a.value); }
          });
          el.classList.remove("fresh"); void el.offsetWidth; el.classList.add("fresh");
        });
        return refreshPage();
      })
      .then(function () { body.setAttribute("data-live-updates", String(1 + parseInt(body.getAttribute("data-live-updates") || "0", 10))); });
  }

  function poll() {
    fetch("/ui/marker", { headers: { Accept: "application/json" }, cache: "no-store", credentials: "same-origin" })
      .then(function (r) {
        if (r.status === 401) { setLive(false, "signed out"); return null; }
        if (!r.ok) { throw new Error("marker: HTTP " + r.status); }
        return r.json();
      })
      .then(function (j) {
        if (j === null) { return "stop"; }
        setLive(true);
        if (j.marker !== marker) { marker = j.marker; return swapLive(); }
      })
      .catch(function () { setLive(false); })
      .then(function (stop) { if (stop !== "stop") { setTimeout(poll, pollMs); } });
  }

  window.addEventListener("resize", function () {
    Object.keys(charts).forEach(function (k) {
      var u = charts[k];
      u.setSize({ width: widthOf(u.root.parentNode), height: u.height });
    });
  });

  function start() {
    loadPage()
      .then(function () { performance.mark("hvcb-ready"); body.setAttribute("data-ready", "1"); })
      .catch(function (e) { body.setAttribute("data-ready", "error"); throw e; });
    if (marker !== null && liveEl) { setTimeout(poll, pollMs); }
  }

  if (document.readyState === "loading") { document.addEventListener("DOMContentLoaded", start); } else { start(); }
})();
