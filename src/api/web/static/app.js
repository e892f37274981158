// graybox dashboard: one page over the JSON API. Views are chosen by the URL's hash
// (#/jobs, #/jobs/ID, #/new, #/compare/ID,ID, #/models, #/models/ID, #/datasets, #/templates;
// the jobs' views are in jobs.js, the models' in models.js, the forms that change things and
// the datasets' and templates' views in forms.js); one stream
// (GET /v1/events, read with fetch so that it can carry the token) keeps every view live.
// Each chart's element carries the data it draws in `data-series` (JSON), for tests and
// for anyone who wants the numbers.
"use strict";

const PAGE_SIZE = 50;
const TOKEN_KEY = "graybox-token";
const root = document.getElementById("view");

// ---------- the API ----------

class ApiError extends Error {
  constructor(status, body) {
    const e = (body && body.error) || {};
    super(e.message || `HTTP ${status}`);
    this.status = status;
    this.field = e.field;
  }
}

function authHeaders() {
  const t = sessionStorage.getItem(TOKEN_KEY);
  return t ? { Authorization: `Bearer ${t}` } : {};
}

async function api(method, path, body, contentType) {
  const headers = authHeaders();
  let payload;
  if (body instanceof Blob || typeof body === "string") {
    payload = body;
    if (contentType) headers["content-type"] = contentType;
  } else if (body !== undefined) {
    payload = JSON.stringify(body);
    headers["content-type"] = "application/json";
  }
  const r = await fetch(path, { method, headers, body: payload });
  const text = await r.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch { data = text; }
  if (r.status === 401) {
    askToken("This service needs a bearer token for this.");
  }
  if (!r.ok) throw new ApiError(r.status, data);
  // An upload answers 201 when it stored the item, 200 when the same bytes were stored before.
  if (method === "POST" && data && typeof data === "object" && !Array.isArray(data) && !("created" in data)) {
    Object.defineProperty(data, "created", { value: r.status === 201, enumerable: false });
  }
  return data;
}

async function download(path, filename) {
  const r = await fetch(path, { headers: authHeaders() });
  if (!r.ok) {
    let body = null;
    try { body = await r.json(); } catch { /* not JSON */ }
    if (r.status === 401) askToken("Downloads need the token.");
    throw new ApiError(r.status, body);
  }
  const url = URL.createObjectURL(await r.blob());
  const a = el("a", { href: url, download: filename });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}

// ---------- the token ----------

const dialog = document.getElementById("token-dialog");
const tokenButton = document.getElementById("token-button");
// The button shows once the service has asked for a token (or one is kept from before):
// a service without one never needs it.
tokenButton.hidden = !sessionStorage.getItem(TOKEN_KEY);
function askToken(why) {
  tokenButton.hidden = false;
  document.getElementById("token-why").textContent = why;
  document.getElementById("token-input").value = sessionStorage.getItem(TOKEN_KEY) || "";
  if (!dialog.open) dialog.showModal();
}
tokenButton.addEventListener("click", () =>
  askToken("The token is kept for this tab only and sent with every request."));
dialog.addEventListener("close", () => {
  if (dialog.returnValue !== "save") return;
  const t = document.getElementById("token-input").value.trim();
  if (t) sessionStorage.setItem(TOKEN_KEY, t); else sessionStorage.removeItem(TOKEN_KEY);
  events.restart();
  route();
});

// ---------- small helpers ----------

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === undefined || v === null || v === false) continue;
    if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else if (k === "text") e.textContent = v;
    else e.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat(Infinity)) {
    if (c !== null && c !== undefined) e.append(c instanceof Node ? c : String(c));
  }
  return e;
}

// Warnings (the data checks at upload, the training checks at a job's end) where they cannot
// be missed: each one's code, field and message.
function warningsBox(warnings, id, title) {
  if (!warnings?.length) return "";
  return el("div", { class: "warnings", role: "status", id },
    el("strong", { text: title }),
    el("ul", {}, warnings.map((w) => el("li", {}, el("code", { text: w.code }), w.field ? ` (${w.field})` : "", `: ${w.message}`))));
}

const fmtLoss = (v) => (v === null || v === undefined ? "–" : Number(v).toExponential(3));
// A best validation loss and the steps it is over (`best_val_loss_steps` of a job or a
// model's metrics: H for a multi-step job's loss over H-step windows; 1, or absent from an
// older service, for the one-step loss, which needs no note).
const stepsNote = (steps) => (Number.isInteger(steps) && steps > 1 ? `${steps}-step` : "");
const bestLossLabel = (steps) => (stepsNote(steps) ? `best val loss (${stepsNote(steps)})` : "best val loss");
const fmtBestLoss = (v, steps) => (stepsNote(steps) && v !== null && v !== undefined ? `${fmtLoss(v)} (${stepsNote(steps)})` : fmtLoss(v));
const fmtTime = (s) => (s ? new Date(s).toLocaleString() : "–");
// In tables: month, day and time, which fit a column (the full time is the cell's title).
const fmtShort = (s) => (s ? new Date(s).toLocaleString(undefined, { month: "short", day: "numeric", hour: "2-digit", minute: "2-digit" }) : "–");
const timeCell = (s) => el("td", { class: "hide-narrow", title: fmtTime(s), text: fmtShort(s) });
function duration(job) {
  if (!job.started_at) return "–";
  const end = job.finished_at ? new Date(job.finished_at) : new Date();
  const s = Math.max(0, (end - new Date(job.started_at)) / 1000);
  return s < 120 ? `${s.toFixed(1)} s` : `${(s / 60).toFixed(1)} min`;
}
const stateBadge = (state) => el("span", { class: `state state-${state}`, text: state });
// A job's model as people name an ensemble of K: "MVB ×5".
function modelLabel(job) {
  const k = job.training?.ensemble;
  return Number.isInteger(k) && k > 1 ? `${job.model} ×${k}` : job.model;
}
const isActive = (job) => job.state === "queued" || job.state === "running";

function errorBox(e) {
  return el("div", { role: "alert", text: e instanceof Error ? e.message : String(e) });
}

function factList(pairs) {
  return el("dl", { class: "facts" }, pairs.flatMap(([k, v]) => [el("dt", { text: k }), el("dd", {}, v)]));
}

// A dataset as people know it: its name, with its id beside it in small print (and as the
// title); the id alone for a dataset without a name, or one no longer stored.
function datasetRef(id, names) {
  if (!id) return "–";
  const name = names?.get(id);
  if (!name) return el("span", { class: "dataset-ref", title: id, text: id });
  return el("span", { class: "dataset-ref", title: id },
    el("span", { class: "dataset-name", text: name }), " ", el("span", { class: "muted small", text: id }));
}

// The names of the datasets `ids` (id → name; a deleted or unnamed dataset has none).
async function loadDatasetNames(ids) {
  const names = new Map();
  await Promise.all([...new Set(ids.filter(Boolean))].map((id) => api("GET", `/v1/datasets/${id}`)
    .then((d) => { if (d?.name) names.set(id, d.name); }, () => { /* shown by its id */ })));
  return names;
}

// ---------- units ----------

// Each coordinate's unit where the model's template says it: a built-in template's, a URDF
// joint's by its type (URDF is in SI units), a formula template's angles (its periodic
// coordinates); null where only the data know.
function coordinateUnits(m) {
  const t = m.spec?.template;
  const builtin = { pendulum: ["rad"], double_pendulum: ["rad", "rad"], cartpole: ["m", "rad"], planar_body: ["m", "m", "rad"] };
  if (typeof t === "string") return builtin[t] ?? Array(m.nv).fill(null);
  if (t?.kind === "urdf" && typeof t.urdf === "string") {
    const robot = new DOMParser().parseFromString(t.urdf, "application/xml").documentElement;
    // The robot's own joints: a <transmission> names joints too, without a type.
    const types = new Map([...robot.querySelectorAll(":scope > joint")].map((j) => [j.getAttribute("name"), j.getAttribute("type")]));
    const byType = { revolute: "rad", continuous: "rad", prismatic: "m" };
    return coordinateNames(m).map((name) => byType[types.get(name)] ?? null);
  }
  const periodic = Array.isArray(t?.periodic) ? t.periodic : [];
  return Array.from({ length: m.nv }, (_, i) => (periodic[i] ? "rad" : null));
}

// Energies and forces are in joules and newtons (metres) when the template is in SI units: a
// built-in one or a URDF robot. A formula template's are in its own.
const siUnits = (m) => typeof m.spec?.template === "string" || m.spec?.template?.kind === "urdf";
const rateUnit = (u) => (u ? `${u}/s` : null);
const forceUnit = (u) => ({ rad: "N·m", m: "N" })[u] ?? null;
const withUnit = (label, unit) => (unit ? `${label} (${unit})` : label);
// The one unit every coordinate shares, or null.
const sharedUnit = (units) => (units.length && units.every((u) => u && u === units[0]) ? units[0] : null);

// ---------- charts ----------

// A band's fill: its curve's colour at 20 % opacity (hex alpha).
const BAND_ALPHA = "33";
const PALETTE = ["#2457c5", "#d9480f", "#2b8a3e", "#862e9c", "#c92a2a", "#1098ad", "#e67700", "#5c940d"];

// TensorBoard's smoothing: an exponential moving average, debiased for its first points.
function ema(values, weight) {
  if (!weight) return values.slice();
  let last = 0, n = 0;
  return values.map((v) => {
    if (v === null || !Number.isFinite(v)) return v;
    last = last * weight + (1 - weight) * v;
    n += 1;
    return last / (1 - Math.pow(weight, n));
  });
}

// A uPlot chart in `host`: x values and named series; the data drawn is in data-series.
function chart(host, { x, series, xLabel, yLabel, logY = false, logX = false, dashed = [], bands = [] }) {
  host.replaceChildren();
  host.classList.add("chart");
  host.dataset.series = JSON.stringify({ x, x_label: xLabel, y_label: yLabel, series, bands });
  const names = Object.keys(series);
  // A band's edges (an ensemble's mean ± σ) are thin lines in their curve's colour, filled
  // between; every other curve takes the next colour.
  const edgeOf = new Map(bands.flatMap((b) => [[b.upper, b.of], [b.lower, b.of]]));
  const colour = new Map();
  names.filter((n) => !edgeOf.has(n)).forEach((n, i) => colour.set(n, PALETTE[i % PALETTE.length]));
  const stroke = (n) => colour.get(edgeOf.get(n) ?? n) ?? PALETTE[0];
  const width = Math.max(280, host.clientWidth || host.parentElement.clientWidth || 600);
  const opts = {
    width, height: 300,
    scales: { x: logX ? { time: false, distr: 3 } : { time: false }, y: logY ? { distr: 3 } : {} },
    axes: [{ label: xLabel }, {
      label: yLabel, size: 70,
      // Losses span decades: powers of ten as 1e-3, not as rounded zeros.
      values: logY ? (u, vals) => vals.map((v) => (v === null ? "" : Number(v).toExponential(0))) : undefined,
    }],
    series: [{ label: xLabel }, ...names.map((name) => ({
      label: name, stroke: stroke(name), width: edgeOf.has(name) ? 0.5 : 1.5,
      dash: dashed.includes(name) ? [6, 4] : undefined, spanGaps: true,
    }))],
    bands: bands.map((b) => ({
      series: [names.indexOf(b.upper) + 1, names.indexOf(b.lower) + 1], fill: stroke(b.of) + BAND_ALPHA,
    })),
  };
  const clean = (v) => (v === null || !Number.isFinite(v) || (logY && v <= 0) ? null : v);
  const data = [x, ...names.map((n) => series[n].map(clean))];
  const plot = new uPlot(opts, data, host);
  host._plot = plot;
  return plot;
}

window.addEventListener("resize", () => {
  for (const host of document.querySelectorAll(".chart")) {
    if (host._plot) host._plot.setSize({ width: Math.max(280, host.clientWidth), height: 300 });
  }
});

// ---------- the one event stream ----------

const events = {
  listeners: new Set(),
  controller: null,
  on(fn) { this.listeners.add(fn); return () => this.listeners.delete(fn); },
  restart() { if (this.controller) this.controller.abort(); this.start(); },
  async start() {
    const controller = new AbortController();
    this.controller = controller;
    while (!controller.signal.aborted) {
      try {
        const r = await fetch("/v1/events", { headers: authHeaders(), signal: controller.signal });
        if (r.status === 401) return; // reads need the token: restarted once it is given
        if (!r.ok || !r.body) throw new Error(`events: HTTP ${r.status}`);
        const reader = r.body.getReader();
        const decoder = new TextDecoder();
        let buffer = "";
        for (;;) {
          const { value, done } = await reader.read();
          if (done) break;
          buffer += decoder.decode(value, { stream: true });
          let end;
          while ((end = buffer.indexOf("\n\n")) >= 0) {
            this.dispatch(buffer.slice(0, end));
            buffer = buffer.slice(end + 2);
          }
        }
      } catch (e) {
        if (controller.signal.aborted) return;
      }
      await new Promise((ok) => setTimeout(ok, 2000)); // the service restarted: reconnect
    }
  },
  dispatch(block) {
    let type = "message", data = "";
    for (const line of block.split("\n")) {
      if (line.startsWith("event:")) type = line.slice(6).trim();
      else if (line.startsWith("data:")) data += line.slice(5).trim();
    }
    if (!data) return;
    const payload = JSON.parse(data);
    for (const fn of this.listeners) fn(type, payload);
  },
};

// ---------- views ----------

let cleanup = [];
function onLeave(fn) { cleanup.push(fn); }

async function route() {
  for (const fn of cleanup) fn();
  cleanup = [];
  const [section, arg] = location.hash.replace(/^#\/?/, "").split("/");
  for (const a of document.querySelectorAll("[data-nav]")) {
    if (a.dataset.nav === (section || "jobs")) a.setAttribute("aria-current", "page");
    else a.removeAttribute("aria-current");
  }
  // Each visit renders into its own element: a visit still waiting on the API when the next
  // one starts writes into a detached element, never into the page.
  const view = el("div");
  root.replaceChildren(view);
  try {
    if (!section || section === "jobs") await (arg ? jobView(view, arg) : jobsView(view));
    else if (section === "new") await newJobView(view);
    else if (section === "templates") await templatesView(view);
    else if (section === "compare") await compareView(view, arg.split(",").filter(Boolean));
    else if (section === "models") await (arg ? modelView(view, arg) : modelsView(view));
    else if (section === "datasets") await datasetsView(view);
    else view.append(el("h1", { text: "Not found" }), el("p", {}, el("a", { href: "#/jobs", text: "Jobs" })));
  } catch (e) {
    view.append(errorBox(e));
  }
}
window.addEventListener("hashchange", route);

events.start();
route();
