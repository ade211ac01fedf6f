/* loopworks faceplate: the overview and a loop's faceplate, fed by server-sent events.
   Plain JavaScript, no framework; the trend is uPlot (vendored, MIT). Every value shown
   carries its OPC UA quality: Uncertain in orange with "?", Bad as BAD (never a number),
   stale (no link to the controller) hatched and greyed. Test hooks: window.__lw. */
(() => {
  "use strict";
  const PAGE = document.body.dataset.page;
  const LOOP = document.body.dataset.loop || null;
  const TREND_WINDOWS = [60, 300, 900];
  const SILENT_AFTER = 3000; // ms without an event: the page marks everything stale
  const lw = (window.__lw = {
    events: 0, trendLength: 0, lastX: null, lastRow: null, stale: null, connected: null, result: null,
  });
  let meta = null;
  let metaVersion = -1;
  let session = { user: null };
  let last = null;
  let lastEventAt = 0;
  let counters = []; // [[t, {COMM_ERRORS, OVERRUNS, READBACK_MISMATCHES}]] of this loop
  let trendWindow = 300;
  let plot = null;
  let trendData = [[], [], [], []];
  let built = false;

  // -- small helpers ---------------------------------------------------------------------
  const $ = (sel) => document.querySelector(sel);
  function el(tag, attrs, ...kids) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined || v === false) continue;
      if (k === "class") e.className = v;
      else if (k === "text") e.textContent = v;
      else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
      else e.setAttribute(k, v === true ? "" : v);
    }
    for (const kid of kids) if (kid !== null && kid !== undefined)
      e.append(typeof kid === "string" ? document.createTextNode(kid) : kid);
    return e;
  }
  // digits: decimals; "exact": a setting as given, to 6 significant digits (a tuning value:
  // ALPHA 0.125 showed as 0.13, RESET 1e9 pushed the panel apart)
  function fmt(v, digits) {
    if (typeof v !== "number") return v === null || v === undefined ? "" : String(v);
    if (digits === "exact") return String(Number(v.toPrecision(6)));
    const d = digits === undefined ? (Math.abs(v) >= 1000 ? 0 : Math.abs(v) >= 100 ? 1 : 2) : digits;
    return v.toFixed(d);
  }
  function clock(t) {
    return new Date(t * 1000).toLocaleTimeString([], { hour12: false });
  }
  function points() { return (meta && LOOP && meta.loops[LOOP]) || {}; }
  function loopState(loop) { return (last && last.loops && last.loops[loop]) || null; }
  function val(loop, name) {
    const s = loopState(loop);
    return s && s.values[name] ? s.values[name] : null;
  }
  function isStale(loop) {
    const s = loopState(loop);
    return !last || !last.link.connected || !s || s.stale || Date.now() - lastEventAt > SILENT_AFTER;
  }
  function modeName(loop, name) {
    const v = val(loop, name + "_TEXT") || val(loop, name);
    if (!v || v[0] === null) return "";
    if (typeof v[0] === "string") return v[0];
    const p = meta && meta.loops[loop] && meta.loops[loop][name];
    return p && p.enum[v[0]] !== undefined ? p.enum[v[0]] : String(v[0]);
  }
  function num(loop, name) {
    const v = val(loop, name);
    return v && typeof v[0] === "number" ? v[0] : null;
  }
  function scale(loop, which) {
    const lo = num(loop, which + "_SCALE_EU_0");
    const hi = num(loop, which + "_SCALE_EU_100");
    return lo !== null && hi !== null && hi !== lo ? [Math.min(lo, hi), Math.max(lo, hi)] : [0, 100];
  }
  function units(loop, name) {
    const p = meta && meta.loops[loop] && meta.loops[loop][name];
    return p ? p.units : "";
  }

  /* Show a value [value, status, quality] in a cell: Bad as BAD, Uncertain as "n ?" in
     orange, stale hatched; the status name in the cell's title and data-status. */
  function show(cell, v, stale, digits) {
    if (!cell) return;
    let text = "—", q = "none", status = "";
    if (v) {
      [, status, q] = v;
      if (q === "bad") text = "BAD";
      else if (v[0] === null) text = "—";
      else text = fmt(v[0], digits) + (q === "uncertain" ? " ?" : "");
    }
    if (stale) q = "stale";
    cell.textContent = text;
    cell.className = cell.className.replace(/\bq-\S+/g, "").trim() + " q-" + q;
    cell.dataset.status = stale ? "stale" : status;
    cell.title = stale ? "stale: no fresh value from the controller" : status;
  }

  // -- the server ------------------------------------------------------------------------
  async function api(path, body) {
    const opts = { method: body === undefined ? "GET" : "POST", headers: {}, credentials: "same-origin" };
    if (body !== undefined) {
      opts.headers["Content-Type"] = "application/json";
      if (session.csrf) opts.headers["X-CSRF-Token"] = session.csrf;
      opts.body = JSON.stringify(body);
    }
    const r = await fetch(path, opts);
    let data = null;
    try { data = await r.json(); } catch (e) { data = null; }
    return { ok: r.ok, status: r.status, data };
  }

  function toast(text, kind) {
    const t = $("#toast");
    t.textContent = text;
    t.className = "toast show " + (kind || "");
    clearTimeout(toast.timer);
    toast.timer = setTimeout(() => { t.className = "toast " + (kind || ""); }, 6000);
  }

  /* A change of `name` to `value` on this loop; the answer (the controller's status code)
     goes to the result line and a toast. */
  async function change(name, value) {
    const result = $("#result");
    let r;
    try {
      r = await api(`/api/loop/${encodeURIComponent(LOOP)}/write`, { name, value });
    } catch (e) {
      r = { ok: false, data: { code: "NoFaceplate", message: "the faceplate server did not answer" } };
    }
    const d = r.data || {};
    let code = d.code || `HTTP ${r.status}`;
    let msg = d.message || "";
    if (!d.code && d.detail) {
      code = d.detail.code || "Refused";
      msg = d.detail.message || JSON.stringify(d.detail);
    }
    const text = r.ok ? `${name} = ${value}: accepted by the controller`
      : `${name} = ${value} refused: ${code}${msg ? " — " + msg : ""}`;
    lw.result = { ok: r.ok, code, text };
    if (result) {
      result.textContent = text;
      result.className = "result " + (r.ok ? "ok" : "err");
      result.dataset.code = code;
    }
    toast(text, r.ok ? "ok" : "err");
    if (code === "SessionEnded") await loadSession();  // shows the page logged out
    return r.ok;
  }

  // -- login -----------------------------------------------------------------------------
  function showSession() {
    $("#user").textContent = session.user ? `${session.user}` : "not logged in: view only";
    $("#login-open").hidden = !!session.user;
    $("#logout").hidden = !session.user;
    document.body.classList.toggle("logged-in", !!session.user);
  }
  async function loadSession() {
    const r = await api("/api/session");
    session = r.ok && r.data ? r.data : { user: null };
    showSession();
  }
  function wireLogin() {
    const form = $("#login");
    $("#login-open").addEventListener("click", () => {
      form.hidden = false;
      form.elements.user.focus();
    });
    $("#login-cancel").addEventListener("click", () => { form.hidden = true; });
    form.addEventListener("submit", async (ev) => {
      ev.preventDefault();
      const msg = $("#login-msg");
      msg.textContent = "logging in…";
      const r = await api("/api/login", { user: form.elements.user.value, password: form.elements.password.value });
      form.elements.password.value = "";
      if (r.ok) {
        session = r.data;
        form.hidden = true;
        msg.textContent = "";
        showSession();
        toast(`logged in as ${session.user}`, "ok");
      } else {
        const d = (r.data && r.data.detail) || {};
        msg.textContent = `refused: ${d.code || r.status}${d.message ? " — " + d.message : ""}`;
      }
    });
    $("#logout").addEventListener("click", async () => {
      await api("/api/logout", {});
      session = { user: null };
      showSession();
    });
  }

  // -- alarms ----------------------------------------------------------------------------
  function alarms(loop) {
    const out = [];
    if (!last || !last.link.connected) {
      const since = last ? clock(last.link.since) : "";
      out.push(["bad", `CONTROLLER LINK LOST${since ? " since " + since : ""}: values are stale` +
        (last && last.link.error ? ` (${last.link.error})` : "")]);
      return out;
    }
    if (Date.now() - lastEventAt > SILENT_AFTER) {
      out.push(["bad", "NO UPDATES from the faceplate server: values are stale"]);
      return out;
    }
    const s = loopState(loop);
    if (s && !s.scanning) out.push(["bad", "CONTROLLER NOT SCANNING: values are stale"]);
    for (const name of ["PV", "SP", "OUT"]) {
      const v = val(loop, name);
      if (v && v[2] === "bad") out.push(["bad", `${name} BAD: ${v[1]}` + (name === "PV" ? " (I/O fault)" : "")]);
      else if (v && v[2] === "uncertain") out.push(["uncertain", `${name} UNCERTAIN: ${v[1]}`]);
    }
    const target = modeName(loop, "MODE"), actual = modeName(loop, "MODE_ACTUAL");
    if (target && actual && target !== actual)
      out.push(["uncertain", `MODE: target ${target}, actual ${actual}`]);
    if (loop === LOOP && counters.length > 1) {
      const [, first] = counters[0], [, now] = counters[counters.length - 1];
      const rising = (k) => now[k] !== null && first[k] !== null && now[k] > first[k];
      if (rising("COMM_ERRORS")) out.push(["bad", `I/O COMMUNICATION ERRORS (${fmt(now.COMM_ERRORS, 0)} in all)`]);
      if (rising("OVERRUNS")) out.push(["uncertain", `SCAN OVERRUNS (${fmt(now.OVERRUNS, 0)} in all)`]);
      if (rising("READBACK_MISMATCHES")) out.push(["uncertain", "OUTPUT READBACK MISMATCH"]);
    }
    return out;
  }
  function showAlarms(box, loop) {
    if (!box) return;
    const list = alarms(loop);
    box.replaceChildren(...(list.length ? list.map(([k, t]) => el("li", { class: "alarm " + k, text: t }))
      : [el("li", { class: "alarm none", text: "no active alarms" })]));
  }

  // -- overview --------------------------------------------------------------------------
  function buildOverview() {
    const main = $("#main");
    main.replaceChildren();
    const grid = el("div", { class: "tiles", id: "tiles" });
    for (const loop of Object.keys(meta.loops)) {
      const row = (name) => el("div", { class: "kv" }, el("span", { class: "k", text: name }),
        el("span", { class: "v", "data-v": name }), el("span", { class: "u", text: units(loop, name) }));
      grid.append(el("a", { class: "tile", href: `/loop/${encodeURIComponent(loop)}`, "data-loop": loop },
        el("div", { class: "tile-head" }, el("span", { class: "tag", text: loop }),
          el("span", { class: "mode", "data-v": "mode" }), el("span", { class: "badge", "data-v": "badge" })),
        el("div", { class: "tile-body" },
          el("div", { class: "hbar pvbar", title: "PV (bar), SP (marker)" }, el("div", { class: "fill" }),
            el("div", { class: "spmark" })),
          row("PV"), row("SP"), row("OUT")),
        el("ul", { class: "alarms", "data-v": "alarms" })));
    }
    if (!Object.keys(meta.loops).length) grid.append(el("p", { class: "waiting", text: "Waiting for the controller…" }));
    main.append(el("h1", { text: "Loops" }), grid);
  }
  function updateOverview() {
    for (const tile of document.querySelectorAll(".tile")) {
      const loop = tile.dataset.loop;
      const stale = isStale(loop);
      tile.classList.toggle("stale", stale);
      for (const name of ["PV", "SP", "OUT"]) show(tile.querySelector(`[data-v="${name}"]`), val(loop, name), stale);
      const target = modeName(loop, "MODE"), actual = modeName(loop, "MODE_ACTUAL");
      const mode = tile.querySelector('[data-v="mode"]');
      mode.textContent = actual && target && actual !== target ? `${actual} (→${target})` : actual || target;
      mode.classList.toggle("mismatch", !!(actual && target && actual !== target));
      const badge = tile.querySelector('[data-v="badge"]');
      badge.textContent = stale ? "STALE" : "";
      bar(tile.querySelector(".pvbar"), loop, stale, true);
      showAlarms(tile.querySelector('[data-v="alarms"]'), loop);
    }
  }

  function pct(v, [lo, hi]) { return Math.max(0, Math.min(100, ((v - lo) / (hi - lo)) * 100)); }
  function bar(box, loop, stale, horizontal) {
    if (!box) return;
    const pv = val(loop, "PV"), sp = num(loop, "SP");
    const sc = scale(loop, "PV");
    const fill = box.querySelector(".fill"), mark = box.querySelector(".spmark");
    const prop = horizontal ? "width" : "height", pos = horizontal ? "left" : "bottom";
    const ok = pv && typeof pv[0] === "number" && pv[2] !== "bad";
    fill.style[prop] = ok ? pct(pv[0], sc) + "%" : "0%";
    fill.className = "fill q-" + (stale ? "stale" : pv ? pv[2] : "none");
    mark.style[pos] = sp !== null ? pct(sp, sc) + "%" : "-100%";
  }

  // -- the faceplate ---------------------------------------------------------------------
  function field(name, label, digits) {
    return el("div", { class: "field" }, el("span", { class: "k", text: label || name }),
      el("span", { class: "v big", id: `v-${name}`, "data-digits": digits === undefined ? "" : digits }),
      el("span", { class: "u", text: units(LOOP, name) }));
  }
  function entry(name, label, extra) {
    const input = el("input", { id: `in-${name}`, type: "number", step: "any", inputmode: "decimal",
      "aria-label": `new ${label}` });
    const form = el("form", { class: "entry", id: `form-${name}`,
      onsubmit: async (ev) => {
        ev.preventDefault();
        if (input.value === "") return;
        if (await change(name, Number(input.value))) input.value = "";
      } }, el("label", { for: `in-${name}`, text: label }), input,
      el("button", { type: "submit", id: `set-${name}`, text: "Set" }), ...(extra || []));
    return form;
  }
  // A slew key adds its step to the OUT last asked for while that request is recent (3 s),
  // not to the displayed OUT, which lags the controller by a refresh: three quick clicks of
  // +1 ask for +1, +2, +3 (on the displayed value they asked for +1 three times).
  let slewTarget = null;
  function slew(delta) {
    return el("button", { type: "button", class: "slew", "data-slew": delta, text: (delta > 0 ? "+" : "−") + Math.abs(delta),
      onclick: () => {
        const recent = slewTarget && Date.now() < slewTarget.until;
        const base = recent ? slewTarget.value : num(LOOP, "OUT");
        if (base === null) return;
        const target = Math.round((base + delta) * 100) / 100;
        slewTarget = { value: target, until: Date.now() + 3000 };
        change("OUT", target).then((ok) => { if (!ok) slewTarget = null; });
      } });
  }
  function buildLoop() {
    const main = $("#main");
    main.replaceChildren();
    if (!meta.loops[LOOP]) {
      main.append(el("p", { class: "waiting", text: Object.keys(meta.loops).length
        ? `The controller has no loop ${LOOP}.` : "Waiting for the controller…" }));
      return;
    }
    const p = points();
    const modes = (p.MODE && p.MODE.enum.length ? ["MAN", "AUTO", "CAS"].filter((m) => p.MODE.enum.includes(m)) : []);
    const face = el("section", { class: "panel face", id: "face" },
      el("div", { class: "face-head" }, el("span", { class: "tag", text: LOOP }),
        el("span", { class: "badge", id: "badge" })),
      el("div", { class: "modebox" },
        el("span", { class: "k", text: "Mode" }), el("span", { id: "mode-actual", class: "mode" }),
        el("span", { class: "k", text: "target" }), el("span", { id: "mode-target", class: "mode target" })),
      el("div", { class: "face-body" },
        el("div", { class: "vbar pvbar", title: "PV (bar) and SP (marker)" },
          el("span", { class: "hi", id: "pv-hi" }), el("div", { class: "fill" }), el("div", { class: "spmark" }),
          el("span", { class: "lo", id: "pv-lo" })),
        el("div", { class: "fields" }, field("PV"), field("SP"), field("OUT"),
          el("div", { class: "hbar outbar", title: "OUT" }, el("div", { class: "fill" })))),
      el("div", { class: "buttons" }, ...modes.map((m) => el("button", { type: "button", class: "modebtn", id: `mode-${m}`,
        "data-mode": m, text: m, onclick: () => change("MODE", m) }))),
      p.SP && p.SP.writable ? entry("SP", "SP") : null,
      p.OUT && p.OUT.writable ? entry("OUT", "OUT", [el("span", { class: "slews" }, slew(-10), slew(-1), slew(1), slew(10))]) : null,
      el("p", { id: "result", class: "result", text: "" }));
    const trend = el("section", { class: "panel trend" },
      el("div", { class: "panel-head" }, el("h2", { text: "Trend" }),
        el("select", { id: "window", "aria-label": "trend window",
          onchange: (ev) => { trendWindow = Number(ev.target.value); seedTrend(); } },
          ...TREND_WINDOWS.map((s) => el("option", { value: s, selected: s === trendWindow, text: `${s / 60} min` })))),
      el("div", { id: "chart" }));
    const alarmBox = el("section", { class: "panel" }, el("h2", { text: "Alarms and status" }), el("ul", { id: "alarms", class: "alarms" }));
    const comp = Object.keys(p).filter((n) => n.startsWith("COMP_"));
    let compBox = null;
    if (comp.length) {
      const m = /^compensator (\S+) \(([^)]+)\)/.exec(p[comp[0]].description || "");
      compBox = el("section", { class: "panel", id: "comp" },
        el("h2", { text: "Compensator" }),
        el("p", { class: "u comp-kind", text: m ? `block ${m[1]}, ${m[2]}` : "" }),
        el("p", { class: "comp-state", id: "comp-state" }),
        el("table", { class: "grid" }, el("tbody", {}, ...comp.filter((n) => n !== "COMP_START").map((n) =>
          el("tr", { title: p[n].description }, el("th", { text: n.slice(5).replace(/_/g, " ") }),
            el("td", { class: "v", id: `v-${n}` }), el("td", { class: "u", text: p[n].units }))))));
    }
    const fixed = new Set(["PV", "SP", "OUT", "MODE"]);
    const tuning = Object.keys(p).filter((n) => p[n].writable && !fixed.has(n));
    const tune = el("section", { class: "panel", id: "tuning" }, el("h2", { text: "Tuning" }),
      el("table", { class: "grid" }, el("tbody", {}, ...tuning.map((n) => {
        const input = el("input", { type: "number", step: "any", id: `in-${n}`, "aria-label": `new ${n}` });
        return el("tr", { title: p[n].description },
          el("th", { text: n.replace(/_/g, "_\u200b") }), el("td", { class: "v", id: `v-${n}` }),
          el("td", {}, el("form", { class: "entry small", onsubmit: async (ev) => {
            ev.preventDefault();
            if (input.value !== "" && await change(n, Number(input.value))) input.value = "";
          } }, input, el("button", { type: "submit", text: "Set" }))));
      }))));
    const statNames = ["SCANS", "OVERRUNS", "LATE_P99_MS", "LATE_MAX_MS", "COMM_ERRORS", "READBACK_MISMATCHES"]
      .filter((n) => p[n]);
    const stats = el("section", { class: "panel", id: "stats" }, el("h2", { text: "Scans" }),
      el("table", { class: "grid" }, el("tbody", {}, ...statNames.map((n) =>
        el("tr", {}, el("th", { text: n.replace(/_/g, " ").toLowerCase() }), el("td", { class: "v", id: `v-${n}` }))))));
    main.append(el("div", { class: "fp" }, face, trend, el("div", { class: "side" }, alarmBox, compBox, tune, stats)));
    makePlot();
    seedTrend();
  }

  function updateLoop() {
    if (!meta || !meta.loops[LOOP]) return;
    const stale = isStale(LOOP);
    document.body.classList.toggle("stale", stale);
    $("#badge").textContent = stale ? "STALE" : "";
    for (const name of ["PV", "SP", "OUT"]) show($(`#v-${name}`), val(LOOP, name), stale);
    const target = modeName(LOOP, "MODE"), actual = modeName(LOOP, "MODE_ACTUAL") || target;
    $("#mode-actual").textContent = stale ? "?" : actual;
    $("#mode-target").textContent = stale ? "?" : target;
    $("#mode-actual").classList.toggle("mismatch", !stale && actual !== target);
    for (const b of document.querySelectorAll(".modebtn")) b.classList.toggle("active", b.dataset.mode === target);
    const manual = target === "MAN" || target === "OOS";
    for (const b of document.querySelectorAll("#form-OUT button, #form-OUT input")) b.classList.toggle("inactive", !manual);
    const sc = scale(LOOP, "PV");
    $("#pv-hi").textContent = fmt(sc[1], 0);
    $("#pv-lo").textContent = fmt(sc[0], 0);
    bar($(".vbar"), LOOP, stale, false);
    const out = val(LOOP, "OUT"), osc = scale(LOOP, "OUT");
    const ofill = $(".outbar .fill");
    ofill.style.width = out && typeof out[0] === "number" && out[2] !== "bad" ? pct(out[0], osc) + "%" : "0%";
    ofill.className = "fill q-" + (stale ? "stale" : out ? out[2] : "none");
    for (const n of Object.keys(points())) {
      const cell = document.getElementById(`v-${n}`);
      const setting = points()[n].writable && n !== "MODE";
      if (cell && !["PV", "SP", "OUT"].includes(n)) show(cell, val(LOOP, n), stale, setting ? "exact" : n === "SCANS" || n.endsWith("ERRORS") || n === "OVERRUNS" || n === "READBACK_MISMATCHES" ? 0 : undefined);
    }
    const start = val(LOOP, "COMP_START");
    const cs = $("#comp-state");
    if (cs && start) {
      const on = typeof start[0] === "number" && start[0] !== 0;
      const kick = num(LOOP, "COMP_KICKER_DELT"), dither = num(LOOP, "COMP_DITHER_DELT");
      cs.textContent = stale ? "state unknown (stale)" : !on ? "OFF: passes OUT through to the valve"
        : kick ? `ON: kicking (${fmt(kick)} %)` : dither ? `ON: dithering (${fmt(dither)} %)` : "ON: inside the noise band";
      cs.className = "comp-state " + (stale ? "q-stale" : on ? "on" : "off");
    }
    showAlarms($("#alarms"), LOOP);
  }

  // -- the trend -------------------------------------------------------------------------
  function chartSize() {
    const box = $("#chart");
    const w = Math.max(200, box.clientWidth);
    return { width: w, height: window.innerWidth < 600 ? 220 : window.innerHeight > 1200 ? 420 : 300 };
  }
  function makePlot() {
    const box = $("#chart");
    const opts = Object.assign(chartSize(), {
      cursor: { drag: { x: false, y: false } },
      scales: { x: { time: true }, pv: { auto: false, range: () => scale(LOOP, "PV") },
        out: { auto: false, range: () => scale(LOOP, "OUT") } },
      axes: [{ stroke: "#333", grid: { stroke: "#c4c4c4" }, space: 70,
        values: (u, splits) => splits.map((v) => clock(v)) },
        { scale: "pv", stroke: "#333", grid: { stroke: "#c4c4c4" }, label: "PV, SP" + (units(LOOP, "PV") ? ` [${units(LOOP, "PV")}]` : "") },
        { scale: "out", side: 1, stroke: "#1f6f8b", grid: { show: false }, label: "OUT" + (units(LOOP, "OUT") ? ` [${units(LOOP, "OUT")}]` : "") }],
      series: [{ value: (u, v) => v === null ? "—" : clock(v) },
        { label: "PV", scale: "pv", stroke: "#1b1b1b", width: 2, points: { show: false }, value: (u, v) => v === null ? "—" : fmt(v) },
        { label: "SP", scale: "pv", stroke: "#7a4fb0", width: 2, dash: [8, 4], points: { show: false }, value: (u, v) => v === null ? "—" : fmt(v) },
        { label: "OUT", scale: "out", stroke: "#1f8bab", width: 1.5, points: { show: false }, value: (u, v) => v === null ? "—" : fmt(v) }],
    });
    plot = new uPlot(opts, trendData, box);
    if (window.ResizeObserver) new ResizeObserver(() => plot && plot.setSize(chartSize())).observe(box);
  }
  async function seedTrend() {
    const r = await api(`/api/loop/${encodeURIComponent(LOOP)}/trend?seconds=${trendWindow}`);
    if (r.ok && Array.isArray(r.data)) trendData = r.data;
    drawTrend();
  }
  function drawTrend() {
    if (!plot) return;
    const t = trendData[0];
    if (t.length) {
      const start = t[t.length - 1] - trendWindow;
      let i = 0;
      while (i < t.length && t[i] < start) i++;
      if (i) trendData = trendData.map((c) => c.slice(i));
    }
    plot.setData(trendData);
    lw.trendLength = trendData[0].length;
    lw.lastX = trendData[0].length ? trendData[0][trendData[0].length - 1] : null;
  }
  function appendTrend(sample) {
    const s = sample.loops[LOOP];
    const t = trendData[0];
    if (t.length && sample.t <= t[t.length - 1]) return;
    const ok = (name) => {
      const v = s && s.values[name];
      return sample.link.connected && s && !s.stale && v && typeof v[0] === "number" && v[2] !== "bad" ? v[0] : null;
    };
    const row = [sample.t, ok("PV"), ok("SP"), ok("OUT")];
    row.forEach((x, i) => trendData[i].push(x));
    lw.lastRow = row;
    drawTrend();
  }

  // -- the event stream ------------------------------------------------------------------
  async function loadMeta() {
    const r = await api("/api/meta");
    if (!r.ok) return;
    meta = r.data;
    metaVersion = meta.version;
    built = false;
  }
  function showLink() {
    const link = $("#link");
    const silent = Date.now() - lastEventAt > SILENT_AFTER;
    const up = last && last.link.connected && !silent;
    lw.connected = !!up;
    lw.stale = LOOP ? isStale(LOOP) : !up;
    link.textContent = up ? `controller ${meta ? meta.url : ""}` : silent ? "NO UPDATES" : "CONTROLLER LINK LOST";
    link.className = "link " + (up ? "up" : "down");
    document.body.classList.toggle("link-down", !up);
  }
  function render() {
    if (meta && !built) {
      if (PAGE === "overview") buildOverview(); else buildLoop();
      built = true;
    }
    if (built) { if (PAGE === "overview") updateOverview(); else updateLoop(); }
    showLink();
  }
  async function onSample(sample) {
    last = sample;
    lastEventAt = Date.now();
    lw.events++;
    if (sample.link.version !== metaVersion && sample.link.connected) await loadMeta();
    if (PAGE === "loop" && meta && meta.loops[LOOP]) {
      const s = sample.loops[LOOP];
      if (s) {
        const c = {};
        for (const k of ["COMM_ERRORS", "OVERRUNS", "READBACK_MISMATCHES"]) c[k] = s.values[k] ? s.values[k][0] : null;
        counters.push([sample.t, c]);
        while (counters.length && counters[0][0] < sample.t - 15) counters.shift();
      }
      if (built) appendTrend(sample);
    }
    render();
  }
  function connect() {
    const es = new EventSource("/events");
    es.onmessage = (ev) => { onSample(JSON.parse(ev.data)); };
    es.onerror = () => { render(); };
  }

  wireLogin();
  loadSession();
  loadMeta().then(render);
  connect();
  setInterval(render, 1000); // a silent stream shows as stale even without events
})();
