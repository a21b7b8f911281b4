/* The operation page's recorded channels (service/web/templates/operation_channels.html): the
 * travel as recorded and the coil currents on one time axis, the DCRM, with the command and
 * contact instants marked, and the analyser's figures beside hvcb's. Data: the page's own
 * curves.json (channels, events, analyser_comparison). Text is only ever set as textContent. */
(function () {
  "use strict";

  var COLORS = ["#1f5fa8", "#7a4cc2", "#1b7f3b", "#d9822b", "#b3261e", "#5d6d7e"];
  var charts = {};

  function $(sel) { return document.querySelector(sel); }

  function fmt(v, digits) {
    if (v === null || v === undefined || !isFinite(v)) { return "—"; }
    return Number(v).toPrecision(digits);
  }

  function marks(events) {
    var out = [];
    if (events && events.command_s !== null) { out.push({ t: events.command_s * 1e3, label: "command", color: "#d59b00" }); }
    if (events && events.contact_s !== null) { out.push({ t: events.contact_s * 1e3, label: events.contact_event, color: "#b3261e" }); }
    return out;
  }

  function markHook(list) {
    return function (u) {
      var ctx = u.ctx, top = u.bbox.top, h = u.bbox.height, px = window.devicePixelRatio || 1;
      ctx.save();
      list.forEach(function (m) {
        var x = Math.round(u.valToPos(m.t, "x", true));
        if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) { return; }
        ctx.strokeStyle = m.color;
        ctx.lineWidth = 2 * px;
        ctx.setLineDash([6 * px, 4 * px]);
        ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + h); ctx.stroke();
        ctx.setLineDash([]);
        ctx.fillStyle = m.color;
        ctx.font = (11 * px) + "px sans-serif";
        ctx.fillText(m.label, x + 4 * px, top + 12 * px);
      });
      ctx.restore();
    };
  }

  function chart(key, el, unit, names, t, series, list, range) {
    if (charts[key]) { charts[key].destroy(); }
    el.textContent = "";
    var opts = {
      width: Math.max(280, Math.floor(el.getBoundingClientRect().width || 400)), height: 180,
      series: [{ label: "t [ms]", value: function (u, v) { return v == null ? "—" : v.toFixed(2) + " ms"; } }],
      scales: { x: { time: false, range: function () { return range; } } },
      axes: [{ label: "time [ms]", labelSize: 18 }, { size: 60, label: unit, labelSize: 16 }],
      cursor: { sync: { key: "op" } }, hooks: { draw: [markHook(list)] }
    };
    var data = [t];
    names.forEach(function (n, i) {
      opts.series.push({ label: n + " [" + series[n].unit + "]", stroke: COLORS[i % COLORS.length], width: 1.4,
        points: { show: false }, value: function (u, v) { return fmt(v, 4) + " " + series[n].unit; } });
      data.push(series[n].values);
    });
    charts[key] = new uPlot(opts, data, el);
    el.setAttribute("data-axis-labels", opts.axes.map(function (a) { return a.label || ""; }).join("|"));
  }

  function comparison(rows) {
    var block = $("#comparison-block");
    var tbody = $("#analyser-comparison tbody");
    tbody.textContent = "";
    (rows || []).forEach(function (r) {
      var tr = document.createElement("tr");
      [r.quantity, r.unit, r.channel, fmt(r.analyser, 4), fmt(r.hvcb, 4),
       (r.difference > 0 ? "+" : "") + fmt(r.difference, 3)].forEach(function (text, i) {
        var td = document.createElement("td");
        td.textContent = text;
        if (i >= 3) { td.className = "num"; }
        tr.appendChild(td);
      });
      tbody.appendChild(tr);
    });
    block.hidden = !(rows && rows.length);
  }

  function show(j) {
    var box = $("#record-channels");
    if (!j.channels) { box.hidden = true; return; }
    box.hidden = false;
    var t = j.channels.t.map(function (v) { return v * 1e3; });
    var range = [t[0], t[t.length - 1]];
    var series = j.channels.series;
    var names = Object.keys(series);
    var of = function (kind) { return names.filter(function (n) { return series[n].kind === kind; }); };
    var list = marks(j.events);
    $("#contact-word").textContent = j.events ? j.events.contact_event : "contact";
    chart("record-travel", $('[data-chart="record-travel"]'), "travel [mm]", of("travel"), t, series, list, range);
    chart("coils", $('[data-chart="coils"]'), "coil current [A]", of("coil_current"), t, series, list, range);
    var dcrm = of("resistance").concat(of("dcrm_current"));
    $("#dcrm-block").hidden = !dcrm.length;
    if (of("resistance").length) {
      chart("dcrm", $('[data-chart="dcrm"]'), "resistance [µΩ]", of("resistance"), t, series, list, range);
    }
    var e = j.events || {};
    $("#record-events").textContent = (e.command_s !== null && e.command_s !== undefined ?
      "command at " + fmt(e.command_s * 1e3, 5) + " ms (" + (e.command_source || "coil") + ")" : "no coil command found") +
      (e.contact_s !== null && e.contact_s !== undefined ? "; " + e.contact_event + " at " + fmt(e.contact_s * 1e3, 5) +
       " ms (" + e.contact_source + ")" : "") + "; " + names.length + " recorded channels, min/max-decimated together.";
    comparison(j.analyser_comparison);
  }

  function load(tries) {
    var url = document.body.getAttribute("data-curves-url");
    if (!url || !$("#record-channels")) { return; }
    fetch(url, { headers: { Accept: "application/json" }, cache: "no-store", credentials: "same-origin" })
      .then(function (r) { return r.ok ? r.json() : null; })
      .then(function (j) {
        if (!j) { return; }
        show(j);
        // the comparison needs the fit: look again while it is queued or running
        if ((j.fit_status === "queued" || j.fit_status === "running") && tries > 0) {
          setTimeout(function () { load(tries - 1); }, 2000);
        }
      });
  }

  window.hvcbRecord = { charts: charts };  // for the browser test
  document.addEventListener("DOMContentLoaded", function () { load(60); });
})();
