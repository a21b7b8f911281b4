/* The breaker page's prognosis fan chart (templates/breaker_prognosis.html): per limited parameter,
   the observed compensated values, the projected level with its 5-95 % band, and the limit line. */
(function () {
  "use strict";

  function fmt(x) { return x === null || x === undefined ? "none" : (Math.round(x * 10) / 10).toLocaleString("en"); }

  function summary(p) {
    if (p.status === "crossed") { return p.parameter + " past " + p.limit_text + " (" + fmt(p.limit) + "): " + p.reason; }
    if (p.status !== "ok") { return p.parameter + ": no prognosis (" + p.reason + ")"; }
    var q = p.operations_to_limit;
    var head = p.parameter + " to " + p.limit_text + " (" + fmt(p.limit) + "): ";
    if (!q) {
      return head + "no crossing within " + (p.horizon_years ? p.horizon_years + " years" : fmt(p.horizon_operations) + " operations") +
        " (P = " + (100 * (p.probability_within_horizon || 0)).toFixed(1) + " %)";
    }
    var d = p.date_to_limit;
    var when = d ? ", about " + d.median.slice(0, 10) + " (" + (d.p05 ? d.p05.slice(0, 10) : "?") + " – " +
      (d.p95 ? d.p95.slice(0, 10) : "beyond the horizon") + ")" : "";
    return head + fmt(q.median) + " openings (90 %: " + fmt(q.p05) + " – " + (q.p95 === null ? "beyond the horizon" : fmt(q.p95)) +
      ")" + when + "; trend since the " + p.basis + ", " + p.basis_operations + " fits";
  }

  function chart(box, p) {
    var f = p.fan;
    if (!f || !f.operations || typeof uPlot === "undefined") { return; }
    // one x axis: the fan's grid and the observed fits, merged (uPlot wants one sorted x array)
    var xs = f.operations.concat(f.observed.operations).sort(function (a, b) { return a - b; })
      .filter(function (x, i, a) { return i === 0 || x !== a[i - 1]; });
    function on(src, vals) {
      var m = {}; src.forEach(function (x, i) { m[x] = vals[i]; });
      return xs.map(function (x) { return m[x] === undefined ? null : m[x]; });
    }
    var data = [xs, on(f.observed.operations, f.observed.value), on(f.operations, f.p05),
      on(f.operations, f.median), on(f.operations, f.p95), xs.map(function () { return p.limit; })];
    var opts = {
      width: Math.max(320, Math.min(720, box.clientWidth || 640)), height: 240,
      scales: { x: { time: false } },
      axes: [{ label: "openings since the trend's start" }, { label: p.parameter + " (compensated)" }],
      series: [{},
        { label: "observed", stroke: "#555", width: 0, points: { show: true, size: 4 } },
        { label: "5 %", stroke: "#7aa6d6", dash: [4, 4], spanGaps: true },
        { label: "median", stroke: "#1f5fa8", width: 2, spanGaps: true },
        { label: "95 %", stroke: "#7aa6d6", dash: [4, 4], spanGaps: true },
        { label: "limit", stroke: "#c0392b", width: 2 }],
      bands: [{ series: [4, 2], fill: "rgba(31,95,168,0.15)" }]
    };
    new uPlot(opts, data, box);
  }

  function load(section) {
    var note = section.querySelector("#prognosis-note"), charts = section.querySelector("#prognosis-charts");
    fetch(section.getAttribute("data-prognosis-url"), { headers: { Accept: "application/json" }, cache: "no-store",
      credentials: "same-origin" })
      .then(function (r) { if (!r.ok) { throw new Error("prognosis: HTTP " + r.status); } return r.json(); })
      .then(function (j) {
        charts.textContent = "";
        if (!j.parameters.length) { note.textContent = j.message; return; }
        note.textContent = "";
        j.parameters.forEach(function (p) {
          var fig = document.createElement("figure");
          fig.className = "chart prognosis-chart";
          fig.setAttribute("data-prognosis-param", p.parameter);
          var cap = document.createElement("figcaption");
          cap.className = "small";
          cap.textContent = summary(p);
          fig.appendChild(cap);
          charts.appendChild(fig);
          if (p.status === "ok" || p.status === "crossed") { chart(fig, p); }
        });
      })
      .catch(function (e) { note.textContent = "The prognosis could not be loaded: " + e.message; });
  }

  document.addEventListener("DOMContentLoaded", function () {
    var s = document.getElementById("breaker-prognosis");
    if (s) { load(s); }
  });
})();
