// graybox dashboard: one page over the JSON API. Views are chosen by the URL's hash
// (#/jobs, #/jobs/ID, #/new, #/compare/ID,ID, #/models, #/models/ID, #/datasets, #/templates;
// the forms that change things are in forms.js); one stream
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
const isActive = (job) => job.state === "queued" || job.state === "running";

function errorBox(e) {
  return el("div", { role: "alert", text: e instanceof Error ? e.message : String(e) });
}

function factList(pairs) {
  return el("dl", { class: "facts" }, pairs.flatMap(([k, v]) => [el("dt", { text: k }), el("dd", {}, v)]));
}

// ---------- charts ----------

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
function chart(host, { x, series, xLabel, yLabel, logY = false, logX = false, dashed = [] }) {
  host.replaceChildren();
  host.classList.add("chart");
  host.dataset.series = JSON.stringify({ x, x_label: xLabel, y_label: yLabel, series });
  const names = Object.keys(series);
  const width = Math.max(280, host.clientWidth || host.parentElement.clientWidth || 600);
  const opts = {
    width, height: 300,
    scales: { x: logX ? { time: false, distr: 3 } : { time: false }, y: logY ? { distr: 3 } : {} },
    axes: [{ label: xLabel }, {
      label: yLabel, size: 70,
      // Losses span decades: powers of ten as 1e-3, not as rounded zeros.
      values: logY ? (u, vals) => vals.map((v) => (v === null ? "" : Number(v).toExponential(0))) : undefined,
    }],
    series: [{ label: xLabel }, ...names.map((name, i) => ({
      label: name, stroke: PALETTE[i % PALETTE.length], width: 1.5,
      dash: dashed.includes(name) ? [6, 4] : undefined, spanGaps: true,
    }))],
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

// Jobs: a page of the list, live; filter by state; select to compare.
async function jobsView(view) {
  const params = new URLSearchParams(location.hash.split("?")[1] || "");
  const filter = params.get("state") || "";
  const tokens = [""];
  let datasetNames = null;
  let page = 0;
  const selected = new Set();
  const rows = new Map();

  const compare = el("button", { type: "button", disabled: true, onclick: () => {
    location.hash = `#/compare/${[...selected].join(",")}`;
  } }, "Compare selected");
  const stateSelect = el("select", { id: "state-filter", onchange: (e) => {
    location.hash = e.target.value ? `#/jobs?state=${e.target.value}` : "#/jobs";
  } }, ["", "queued", "running", "succeeded", "failed", "cancelled"].map((s) =>
    el("option", { value: s, selected: s === filter, text: s || "all" })));
  const prev = el("button", { type: "button", class: "secondary", onclick: () => load(page - 1) }, "Previous page");
  const next = el("button", { type: "button", class: "secondary", onclick: () => load(page + 1) }, "Next page");
  const tbody = el("tbody");
  const status = el("p", { class: "muted", "aria-live": "polite" });
  view.append(
    el("h1", { text: "Jobs" }),
    el("div", { class: "toolbar" }, el("a", { class: "button", href: "#/new", id: "new-job" }, "New job"),
      el("label", { for: "state-filter", text: "State" }), stateSelect, compare, prev, next),
    el("div", { class: "table-wrap" }, el("table", { id: "jobs-table" },
      el("caption", { class: "muted", text: "Training jobs, newest first" }),
      el("thead", {}, el("tr", {}, ["", "job", "state", "model", "dataset", "progress", "best val loss", "created", "duration", ""]
        .map((h, i) => el("th", { scope: "col", class: i === 7 ? "hide-narrow" : undefined }, h ? h : el("span", { class: "muted", text: i ? "actions" : "select" }))))),
      tbody)),
    status);

  function renderRow(job, atTop = false) {
    const box = el("input", { type: "checkbox", "aria-label": `select ${job.id}`, checked: selected.has(job.id),
      onchange: (e) => { e.target.checked ? selected.add(job.id) : selected.delete(job.id); compare.disabled = selected.size < 1; } });
    const bar = el("progress", { max: job.epochs || 1, value: job.epoch, "aria-label": `${job.epoch} of ${job.epochs} epochs` });
    const cancel = isActive(job)
      ? el("button", { type: "button", class: "secondary", onclick: async (e) => {
          e.target.disabled = true;
          try { renderRow(await api("POST", `/v1/jobs/${job.id}/cancel`)); } catch (err) { status.replaceChildren(errorBox(err)); e.target.disabled = false; }
        } }, "Cancel")
      : "";
    const tr = el("tr", { "data-job": job.id, "data-state": job.state },
      el("td", {}, box),
      el("td", { class: "name" }, el("a", { href: `#/jobs/${job.id}`, text: job.name || job.id }), job.name ? el("div", { class: "muted small", text: job.id }) : ""),
      el("td", {}, stateBadge(job.state)),
      el("td", { text: job.model }),
      el("td", { class: "name" }, datasetNames?.get(job.dataset_id) || el("span", { class: "muted", text: job.dataset_id })),
      el("td", {}, bar, ` ${job.epoch}/${job.epochs}`),
      el("td", { class: "num", text: fmtLoss(job.best_val_loss) }),
      timeCell(job.created_at),
      el("td", { class: "num", text: duration(job) }),
      el("td", {}, cancel));
    const old = rows.get(job.id);
    if (old) old.replaceWith(tr); else if (atTop) tbody.prepend(tr); else tbody.append(tr);
    rows.set(job.id, tr);
  }

  async function load(p) {
    if (p < 0 || tokens[p] === undefined) return;
    // Datasets by name, read once per visit: what the table shows for each job's dataset.
    if (!datasetNames) {
      datasetNames = new Map();
      for (const d of (await api("GET", "/v1/datasets?page_size=1000")).items) if (d.name) datasetNames.set(d.id, d.name);
    }
    const q = new URLSearchParams({ page_size: PAGE_SIZE });
    if (tokens[p]) q.set("page_token", tokens[p]);
    if (filter) q.set("state", filter);
    const data = await api("GET", `/v1/jobs?${q}`);
    page = p;
    tokens[p + 1] = data.next_page_token || undefined;
    rows.clear();
    tbody.replaceChildren();
    // Not forEach(renderRow): its index would be renderRow's atTop, reversing the page.
    data.items.forEach((job) => renderRow(job));
    prev.disabled = page === 0;
    next.disabled = !data.next_page_token;
    status.textContent = data.items.length ? `Page ${page + 1}` : "No jobs yet.";
  }

  onLeave(events.on((type, job) => {
    if (type === "resync") { load(page); return; }
    if (type !== "job") return;
    const matches = !filter || job.state === filter;
    if (rows.has(job.id)) {
      if (matches) renderRow(job); else { rows.get(job.id).remove(); rows.delete(job.id); }
    } else if (matches && page === 0) {
      renderRow(job, true); // the newest job belongs at the top of the first page
      status.textContent = `Page ${page + 1}`;
      if (rows.size > PAGE_SIZE) load(0); // the page's last row and the next page's start moved
    }
  }));
  await load(0);
}

// Loss curves of one job, live; smoothing and the x-axis are the person's choice.
async function jobView(view, id) {
  let job = await api("GET", `/v1/jobs/${id}`);
  let metrics = (await api("GET", `/v1/jobs/${id}/metrics`)).items;
  const head = el("div");
  const chartHost = el("div", { id: "loss-chart", role: "img", "aria-label": "training and validation loss per epoch" });
  const smooth = el("input", { type: "range", id: "smoothing", min: 0, max: 0.99, step: 0.01, value: 0.6 });
  const smoothValue = el("output", { for: "smoothing", text: "0.60" });
  const xAxis = el("select", { id: "x-axis" }, el("option", { value: "epoch", text: "epoch" }), el("option", { value: "time", text: "wall time (s)" }));
  const settings = el("div");

  function drawHead() {
    head.replaceChildren(
      el("h1", { text: job.name ? `Job ${job.name}` : `Job ${job.id}` }),
      factList([
        ["id", job.id],
        ["state", stateBadge(job.state)],
        ["model", job.model],
        ["dataset", job.dataset_id],
        ["validation", job.validation_dataset_id || "held out from the dataset"],
        ["progress", `${job.epoch} / ${job.epochs} epochs`],
        ["best val loss", fmtLoss(job.best_val_loss)],
        ["created", fmtTime(job.created_at)],
        ["duration", duration(job)],
        ["trained model", job.model_id ? el("a", { href: `#/models/${job.model_id}`, text: job.model_id }) : "–"],
      ]),
      job.error ? el("div", { class: "error", role: "alert", id: "job-error", text: `This job failed: ${job.error}` }) : "",
      warningsBox(job.warnings, "job-warnings", "Training warnings:"));
    settings.replaceChildren(el("h2", { text: "Training settings" }), factList(Object.entries(job.training || {}).map(([k, v]) => [k, v === null ? "–" : String(v)])));
  }
  function draw() {
    const w = Number(smooth.value);
    smoothValue.textContent = w.toFixed(2);
    let t = 0;
    const x = xAxis.value === "epoch" ? metrics.map((m) => m.epoch) : metrics.map((m) => (t += m.seconds));
    const train = metrics.map((m) => m.train_loss);
    const val = metrics.map((m) => (m.val_loss === null ? null : m.val_loss));
    const series = { train: ema(train, w), validation: ema(val, w) };
    // A multi-step job: its validation loss over windows of its horizon too.
    const horizon = metrics.map((m) => m.val_horizon_loss ?? null);
    const horizonName = `validation, ${job.training?.horizon ?? "H"} steps`;
    if (horizon.some((v) => v !== null)) series[horizonName] = ema(horizon, w);
    chart(chartHost, {
      x, xLabel: xAxis.value === "epoch" ? "epoch" : "wall time (s)", yLabel: "loss (log scale)", logY: true,
      series,
    });
    chartHost.dataset.raw = JSON.stringify({ train, validation: val });
  }
  smooth.addEventListener("input", draw);
  xAxis.addEventListener("change", draw);
  view.append(head, el("div", { class: "card" },
    el("div", { class: "toolbar" },
      el("label", { for: "smoothing", text: "Smoothing" }), smooth, smoothValue,
      el("label", { for: "x-axis", text: "x-axis" }), xAxis),
    chartHost), settings);
  drawHead();
  draw();
  onLeave(events.on(async (type, j) => {
    if (type !== "job" || j.id !== id) return;
    job = j;
    metrics = (await api("GET", `/v1/jobs/${id}/metrics`)).items;
    drawHead();
    draw();
  }));
}

// Several jobs' validation curves on one chart, and their settings side by side.
async function compareView(view, ids) {
  view.append(el("h1", { text: `Compare ${ids.length} jobs` }));
  if (!ids.length) { view.append(el("p", { text: "Select jobs in the Jobs table first." })); return; }
  const jobs = await Promise.all(ids.map((id) => api("GET", `/v1/jobs/${id}`)));
  const metrics = await Promise.all(ids.map((id) => api("GET", `/v1/jobs/${id}/metrics`).then((m) => m.items)));
  const epochs = Math.max(0, ...metrics.map((m) => m.length ? m[m.length - 1].epoch : 0));
  const x = Array.from({ length: epochs }, (_, i) => i + 1);
  const series = {};
  jobs.forEach((job, k) => {
    const byEpoch = new Map(metrics[k].map((m) => [m.epoch, m.val_loss ?? m.train_loss]));
    series[`${job.id} (${job.model})`] = x.map((e) => byEpoch.get(e) ?? null);
  });
  const host = el("div", { id: "compare-chart", role: "img", "aria-label": "validation loss per epoch of each job" });
  view.append(el("div", { class: "card" }, el("h2", { text: "Validation loss" }), host));
  chart(host, { x, series, xLabel: "epoch", yLabel: "validation loss (log scale)", logY: true });
  const keys = [...new Set(jobs.flatMap((j) => Object.keys(j.training || {})))];
  const row = (label, f) => el("tr", {}, el("th", { scope: "row", text: label }), jobs.map((j, k) => el("td", {}, f(j, k))));
  view.append(el("h2", { text: "Settings and results" }), el("div", { class: "table-wrap" }, el("table", { id: "compare-table" },
    el("thead", {}, el("tr", {}, el("th", { scope: "col", text: "" }), jobs.map((j) => el("th", { scope: "col" }, el("a", { href: `#/jobs/${j.id}`, text: j.id }))))),
    el("tbody", {},
      row("model", (j) => j.model),
      row("state", (j) => stateBadge(j.state)),
      row("dataset", (j) => j.dataset_id),
      keys.map((key) => row(key, (j) => String(j.training?.[key] ?? "–"))),
      row("epochs run", (j) => String(j.epoch)),
      row("best val loss", (j) => fmtLoss(j.best_val_loss)),
      row("final train loss", (j) => fmtLoss(j.train_loss)),
      row("duration", (j) => duration(j))))));
  // The trained models' median open-loop error on one dataset, a line each.
  const trained = jobs.filter((j) => j.model_id).map((j) => ({ id: j.model_id, label: `${j.id} (${j.model})` }));
  if (!trained.length) return;
  const datasets = (await api("GET", "/v1/datasets?page_size=1000")).items;
  const dsSelect = el("select", { id: "compare-dataset" }, datasets.map((d) => el("option", { value: d.id, text: `${d.name || d.id} (${d.count} rows)` })));
  dsSelect.value = jobs[0].dataset_id;
  horizonPanel(view, trained, dsSelect, el("label", { for: "compare-dataset", text: "Trajectories" }), dsSelect);
}

async function modelsView(view) {
  const tbody = el("tbody");
  const empty = el("p", { class: "muted" });
  async function load() {
    const data = await api("GET", `/v1/models?page_size=${PAGE_SIZE}`);
    tbody.replaceChildren(...data.items.map((m) => el("tr", { "data-model": m.id },
      el("td", { class: "name" }, el("a", { href: `#/models/${m.id}`, text: m.name }), el("div", { class: "muted small", text: m.id })),
      el("td", { text: m.origin }),
      el("td", { class: "num", text: m.n }), el("td", { class: "num", text: m.m }), el("td", { class: "num", text: m.dt }),
      el("td", { class: "num", text: fmtLoss(m.metrics?.best_val_loss) }), timeCell(m.created_at))));
    empty.textContent = data.items.length ? "" : "No models yet: they appear when a job succeeds, or upload a model file.";
  }
  view.append(el("h1", { text: "Models" }), el("div", { class: "table-wrap" }, el("table", { id: "models-table" },
    el("thead", {}, el("tr", {}, ["model", "origin", "n", "m", "Δt", "best val loss", "created"].map((h, i) =>
      el("th", { scope: "col", class: i === 6 ? "hide-narrow" : undefined, text: h })))), tbody)),
  empty, modelUploadForm(load));
  await load();
}

// A model: what it is, what it learned, and its replay of recorded trajectories.
async function modelView(view, id) {
  const m = await api("GET", `/v1/models/${id}`);
  const isUrdf = JSON.stringify(m.spec).includes('"kind":"urdf"');
  const notice = el("div", { role: "alert", id: "model-alert" });
  const buttons = el("div", { class: "toolbar" },
    el("button", { type: "button", onclick: () => download(`/v1/models/${id}/checkpoint`, `${id}.gbx`).catch((e) => notice.replaceChildren(errorBox(e))) }, "Download model (.gbx)"),
    isUrdf ? el("button", { type: "button", onclick: () => download(`/v1/models/${id}/urdf`, `${id}.urdf`).catch((e) => notice.replaceChildren(errorBox(e))) }, "Download URDF") : "",
    deleteButton(`/v1/models/${m.id}`, `model ${m.name}`, notice, () => { location.hash = "#/models"; }));
  const physical = Object.entries(m.physical_parameters || {});
  const identifiable = Array.isArray(m.identifiable) ? m.identifiable : [];
  view.append(...[
    el("h1", { text: `Model ${m.name}` }), buttons, notice,
    warningsBox(m.metrics?.warnings, "model-warnings", "Training warnings:"),
    el("div", { class: "card" }, factList([
      ["id", m.id], ["origin", m.origin],
      ["job", m.job_id ? el("a", { href: `#/jobs/${m.job_id}`, text: m.job_id }) : "uploaded"],
      ["n (coordinates)", `${m.n}: ${coordinateNames(m).join(", ")}`], ["m (inputs)", String(m.m)], ["Δt", `${m.dt} s`],
      ["best val loss", fmtLoss(m.metrics?.best_val_loss)], ["epochs", String(m.metrics?.epochs ?? "–")],
      ["created", fmtTime(m.created_at)],
    ])),
    el("h2", { text: "Spec" }), specView(m.spec),
    physical.length ? [
      el("h2", { text: "Learned physical parameters" }),
      el("div", { class: "table-wrap" }, el("table", { id: "physical-table" },
        el("thead", {}, el("tr", {}, el("th", { scope: "col", text: "parameter" }), el("th", { scope: "col", text: "value" }))),
        el("tbody", {}, physical.map(([k, v]) => el("tr", {}, el("td", { text: k }), el("td", { class: "num", text: Number(v).toPrecision(6) })))))),
      identifiable.length ? [el("h3", { text: "Identifiable combinations" }), el("ul", {}, identifiable.map((c) => el("li", { text: `${c.name} = ${Number(c.value).toPrecision(6)}` })))] : "",
      m.identifiability ? el("p", { class: "muted", text: m.identifiability }) : "",
    ] : ""].flat(Infinity));
  await replayPanel(view, m);
}

// The spec as JSON, a template's document (a URDF's XML, long) shortened in place and shown
// whole, collapsed, below.
function specView(spec) {
  const docs = [];
  const shown = JSON.stringify(spec, (key, v) => {
    if (typeof v !== "string" || v.length < 300) return v;
    docs.push(v);
    return `⟨document ${docs.length}: ${v.split("\n").length} lines, below⟩`;
  }, 2);
  return [el("pre", { id: "model-spec", text: shown }), docs.map((d, i) => el("details", { class: "document", id: `spec-document-${i + 1}` },
    el("summary", { text: `Document ${i + 1} (${d.trimStart().startsWith("<") ? "URDF" : "text"}, ${d.split("\n").length} lines)` }),
    el("pre", { text: d })))];
}

const coordinateNames = (m) => m.coordinates || Array.from({ length: m.n }, (_, i) => `q${i + 1}`);

async function replayPanel(view, m) {
  const names = coordinateNames(m);
  const datasets = (await api("GET", "/v1/datasets?page_size=1000")).items.filter((d) => d.n === m.n && d.m === m.m);
  const dsSelect = el("select", { id: "replay-dataset" }, datasets.map((d) => el("option", { value: d.id, text: `${d.name || d.id} (${d.count} rows)` })));
  const trSelect = el("select", { id: "replay-index" });
  const status = el("div", { role: "alert", id: "replay-alert" });
  const charts = el("div", { class: "charts", id: "replay-charts" });
  const go = el("button", { type: "button", id: "replay-button" }, "Replay");
  view.append(el("h2", { text: "Rollout against data" }), el("p", { class: "muted",
    text: "The model predicts a recorded trajectory from its first state with its recorded inputs; recorded and predicted q and q̇ over time." }));
  if (!datasets.length) { view.append(el("p", { text: `No dataset with n = ${m.n}, m = ${m.m}.` })); return; }
  view.append(el("div", { class: "toolbar" },
    el("label", { for: "replay-dataset", text: "Dataset" }), dsSelect,
    el("label", { for: "replay-index", text: "Trajectory" }), trSelect, go), status, charts);

  async function loadTrajectories() {
    const list = await api("GET", `/v1/datasets/${dsSelect.value}/trajectories?page_size=1000`);
    // Longest first: a single transition says little about a model.
    const items = list.items.slice().sort((a, b) => b.length - a.length);
    trSelect.replaceChildren(...items.map((t) => el("option", { value: t.index, text: `#${t.index} (${t.length} steps)` })));
  }
  async function replay() {
    status.replaceChildren();
    try {
      const r = await api("GET", `/v1/models/${m.id}/rollout?dataset_id=${encodeURIComponent(dsSelect.value)}&index=${trSelect.value}`);
      charts.replaceChildren();
      for (const key of ["q", "qdot"]) {
        for (let i = 0; i < m.n; i++) {
          // Coordinates by their names: a URDF's joints, a formula's coordinates.
          const label = key === "q" ? names[i] : `${names[i]} rate`;
          const host = el("div", { class: "replay-chart", "data-variable": `${key}${i}`, role: "img", "aria-label": `${label}, recorded and predicted` });
          charts.append(el("figure", {}, el("figcaption", { text: label }), host));
          chart(host, {
            x: r.t, xLabel: "time (s)", yLabel: label, dashed: ["predicted"],
            series: { recorded: r.recorded[key].map((row) => row[i]), predicted: r.predicted[key].map((row) => row[i]) },
          });
        }
      }
    } catch (e) {
      status.replaceChildren(errorBox(e));
    }
  }
  dsSelect.addEventListener("change", () => loadTrajectories().then(replay));
  go.addEventListener("click", replay);
  await loadTrajectories();
  await replay();
  horizonPanel(view, [{ id: m.id, label: m.id }], dsSelect);
}

// Open-loop error against prediction time on the chosen dataset's trajectories
// (POST /v1/models/{id}/evaluate), both axes logarithmic: one model's median and mean, or
// each compared model's median. `models`: [{id, label}].
function horizonPanel(view, models, dsSelect, ...controls) {
  const horizons = [1, 2, 5, 10, 20, 50, 100, 200, 500];
  const host = el("div", { id: "horizon-chart", role: "img", "aria-label": "open-loop error against prediction time" });
  const status = el("div", { role: "alert", id: "horizon-alert" });
  const go = el("button", { type: "button", id: "horizon-button" }, "Evaluate");
  view.append(el("h2", { text: "Error against horizon" }), el("p", { class: "muted",
    text: "From every state of the dataset's trajectories, the model predicts open loop under the recorded inputs; the median and mean error of q after each horizon (angles on the circle)." }),
    el("div", { class: "toolbar" }, ...controls, go), status, host);
  go.addEventListener("click", async () => {
    status.replaceChildren();
    try {
      const body = { dataset_id: dsSelect.value, horizons };
      const found = await Promise.all(models.map((m) => api("POST", `/v1/models/${m.id}/evaluate`, body)));
      // The same dataset for every model: the same horizons have windows.
      const items = found.map((r) => r.items.filter((e) => e.windows > 0));
      const series = models.length === 1
        ? { median: items[0].map((e) => e.position_median), mean: items[0].map((e) => e.position_mean) }
        : Object.fromEntries(models.map((m, k) => [m.label, items[k].map((e) => e.position_median)]));
      chart(host, {
        x: items[0].map((e) => e.seconds), xLabel: "prediction time (s)", yLabel: "|q̂ − q| (log scale)",
        logX: true, logY: true, series,
      });
    } catch (e) {
      status.replaceChildren(errorBox(e));
    }
  });
}

// Datasets: the list and an upload form (JSON or CSV files).
async function datasetsView(view) {
  const tbody = el("tbody");
  const message = el("div", { role: "alert", id: "upload-alert" });
  const done = el("p", { "aria-live": "polite", id: "upload-status", class: "muted" });
  const warned = el("div");
  const file = el("input", { type: "file", id: "upload-file", accept: ".json,.csv,application/json,text/csv", required: true });
  const name = el("input", { type: "text", id: "upload-name", placeholder: "optional" });
  const dt = el("input", { type: "number", id: "upload-dt", step: "any", min: "0", placeholder: "from the file (needed for CSV)" });
  const form = el("form", { class: "stack card", id: "upload-form" },
    el("h2", { text: "Upload a dataset" }),
    el("label", { for: "upload-file", text: "File (transitions or trajectories as JSON, or CSV)" }), file,
    el("label", { for: "upload-name", text: "Name" }), name,
    el("label", { for: "upload-dt", text: "Δt (s)" }), dt,
    el("div", {}, el("button", { type: "submit" }, "Upload")), message, done, warned);
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    message.replaceChildren();
    done.textContent = "";
    warned.replaceChildren();
    const f = file.files[0];
    if (!f) { message.textContent = "Choose a file first."; return; }
    const q = new URLSearchParams();
    if (name.value) q.set("name", name.value);
    if (dt.value) q.set("dt", dt.value);
    const csv = f.name.toLowerCase().endsWith(".csv");
    try {
      const d = await api("POST", `/v1/datasets?${q}`, f, csv ? "text/csv" : "application/json");
      done.textContent = d.created ? `Uploaded ${d.id} (${d.count} transitions).` : `Already stored as ${d.id}.`;
      warned.replaceChildren(warningsBox(d.warnings, "upload-warnings", "Check the data before training on it:"));
      form.reset();
      await load();
    } catch (err) {
      message.textContent = err.field ? `${err.field}: ${err.message}` : err.message;
    }
  });
  const listStatus = el("div", { role: "alert", id: "datasets-alert" });
  async function load() {
    const data = await api("GET", `/v1/datasets?page_size=${PAGE_SIZE}`);
    tbody.replaceChildren(...data.items.map((d) => el("tr", { "data-dataset": d.id },
      el("td", { class: "name" }, el("span", { class: "dataset-name", text: d.name || "–" }), el("div", { class: "muted small", text: d.id })),
      el("td", { class: "num", text: d.n }), el("td", { class: "num", text: d.m }),
      el("td", { class: "num", text: d.count }), el("td", { class: "num", text: d.dt }),
      el("td", { class: "num", text: `${((d.count * (4 * d.n + d.m) * 8) / 1024).toFixed(1)} KiB` }),
      el("td", { class: "wrap" }, d.warnings?.length ? el("details", { class: "warnings" },
        el("summary", { text: `⚠ ${d.warnings.length} warning${d.warnings.length > 1 ? "s" : ""}` }),
        el("ul", {}, d.warnings.map((w) => el("li", { text: `${w.field ? `${w.field}: ` : ""}${w.message}` })))) : "–"),
      timeCell(d.created_at),
      el("td", {}, deleteButton(`/v1/datasets/${d.id}`, `dataset ${d.name || d.id}`, listStatus, load)))));
  }
  view.append(el("h1", { text: "Datasets" }), form, listStatus, el("div", { class: "table-wrap" }, el("table", { id: "datasets-table" },
    el("thead", {}, el("tr", {}, ["dataset", "n", "m", "count", "Δt", "size", "warnings", "created", ""].map((h, i) => el("th", { scope: "col", class: i === 7 ? "hide-narrow" : undefined, text: h })))),
    tbody)));
  await load();
}

events.start();
route();
