/* The breaker page's prognosis fan chart (templates/breaker_prognosis.html): per limited parameter,
   the observed compensated values, the projected level with its 5-95 % band, and the limit line. */
(function () {
  "use strict";

  // The card's words come with the data (service/prognosis/words.py), so the page, the API and the
  // fleet say the same thing.
  var UNIT = { DO: "s⁻¹", BO: "s⁻²", AO: "s⁻²", EO: "s⁻²", AC: "s⁻²", CC: "s⁻²", latch_time_s: "s" };
  // a characteristic reads in words (service.display.parameter_short); a model symbol as itself
  var WORDS = { latch_time_s: "trip latch time", buffer_ratio: "buffer shock timing against the travel" };

  function val(x, par) {
    if (x === null || x === undefined || !isFinite(x)) { return ""; }
    var a = Math.abs(x), digits = a >= 1000 || a === 0 ? 0 : Math.max(0, 2 - Math.floor(Math.log10(a)));
    return x.toLocaleString("en", { minimumFractionDigits: digits, maximumFractionDigits: digits }).replace("-", "−") +
      (UNIT[par] ? " " + UNIT[par] : "");
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
    var par = p.parameter, obs = f.observed.value, last = obs.length ? obs[obs.length - 1] : null;
    var data = [xs, on(f.observed.operations, obs), on(f.operations, f.p05),
      on(f.operations, f.median), on(f.operations, f.p95)];
    var series = [{},
      { label: "fits, compensated (latest " + val(last, par) + ")", stroke: "#555", width: 0, points: { show: true, size: 4 } },
      { label: "5 %", stroke: "#7aa6d6", dash: [4, 4], spanGaps: true },
      { label: "median (trend level " + val(p.current, par) + ")", stroke: "#1f5fa8", width: 2, spanGaps: true },
      { label: "95 %", stroke: "#7aa6d6", dash: [4, 4], spanGaps: true }];
    // every limit of the breaker file: both sides of a two-sided limit
    var limits = (p.limits && p.limits.length) ? p.limits : [{ direction: p.direction, value: p.limit }];
    limits.forEach(function (l) {
      if (l.value === null || l.value === undefined) { return; }
      data.push(xs.map(function () { return l.value; }));
      series.push({ label: (l.direction === "rising" ? "upper" : "lower") + " limit " + val(l.value, par),
        stroke: "#c0392b", width: 2 });
    });
    var opts = {
      width: Math.max(320, Math.min(720, box.clientWidth || 640)), height: 240,
      scales: { x: { time: false } },
      // no live legend: without a hovered point it would read "--"; the labels carry the values
      legend: { live: false },
      axes: [{ label: "openings since the trend's start" },
        { label: (WORDS[par] || par) + ", compensated" + (UNIT[par] ? " [" + UNIT[par] + "]" : ""), size: 70 }],
      series: series,
      bands: [{ series: [4, 2], fill: "rgba(31,95,168,0.15)" }]
    };
    new uPlot(opts, data, box);
    box.setAttribute("data-axis-labels", opts.axes.map(function (a) { return a.label || ""; }).join("|"));
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
          cap.textContent = p.summary;
          fig.appendChild(cap);
          charts.appendChild(fig);
          if (p.fan && p.fan.operations) { chart(fig, p); }
        });
      })
      .catch(function (e) { note.textContent = "The prognosis could not be loaded: " + e.message; });
  }

  document.addEventListener("DOMContentLoaded", function () {
    var s = document.getElementById("breaker-prognosis");
    if (s) { load(s); }
  });
})();
