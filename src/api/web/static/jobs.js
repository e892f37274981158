// graybox dashboard, the jobs: the list (#/jobs), one job (#/jobs/ID) and several side by
// side (#/compare/ID,ID). Loaded before app.js, whose helpers (el, api, chart, …) these
// functions use when called.
"use strict";

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
      el("td", { class: "model", text: modelLabel(job) }),
      el("td", { class: "name" }, datasetNames?.get(job.dataset_id) || el("span", { class: "muted", text: job.dataset_id })),
      el("td", {}, bar, ` ${job.epoch}/${job.epochs}`),
      el("td", { class: "num", text: fmtBestLoss(job.best_val_loss, job.best_val_loss_steps) }),
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
  const names = await loadDatasetNames([job.dataset_id, job.validation_dataset_id]);
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
        ["model", modelLabel(job)],
        ["dataset", datasetRef(job.dataset_id, names)],
        ["validation", job.validation_dataset_id ? datasetRef(job.validation_dataset_id, names) : "held out from the dataset"],
        ["progress", `${job.epoch} / ${job.epochs} epochs`],
        [bestLossLabel(job.best_val_loss_steps), fmtLoss(job.best_val_loss)],
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
    // A multi-step job's train loss is over windows of H steps, after its one-step epochs: a
    // jump there is the loss changing, not the model getting worse.
    const h = job.training?.horizon ?? 1;
    const p = job.training?.one_step_epochs ?? 0;
    const trainName = h > 1 ? (p > 0 ? `train (1-step to epoch ${p}, then ${h}-step windows)` : `train (${h}-step windows)`) : "train";
    const series = { [trainName]: ema(train, w), validation: ema(val, w) };
    // An ensemble's losses are its members' mean: a band of ± one standard deviation.
    const bands = [];
    for (const [name, key, values] of [[trainName, "train_loss_std", train], ["validation", "val_loss_std", val]]) {
      const std = metrics.map((m) => m[key] ?? null);
      if (!std.some((v) => v !== null)) continue;
      const edge = (sign) => ema(values.map((v, i) => (v === null || std[i] === null ? null : v + sign * std[i])), w);
      series[`${name} + σ`] = edge(1);
      series[`${name} − σ`] = edge(-1);
      bands.push({ of: name, upper: `${name} + σ`, lower: `${name} − σ` });
    }
    // A multi-step job: its validation loss over windows of its horizon too.
    const horizon = metrics.map((m) => m.val_horizon_loss ?? null);
    const horizonName = `validation, ${job.training?.horizon ?? "H"} steps`;
    if (horizon.some((v) => v !== null)) series[horizonName] = ema(horizon, w);
    chart(chartHost, {
      x, xLabel: xAxis.value === "epoch" ? "epoch" : "wall time (s)", yLabel: "loss (log scale)", logY: true,
      series, bands,
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
  const names = await loadDatasetNames(jobs.flatMap((j) => [j.dataset_id, j.validation_dataset_id]));
  const epochs = Math.max(0, ...metrics.map((m) => m.length ? m[m.length - 1].epoch : 0));
  const x = Array.from({ length: epochs }, (_, i) => i + 1);
  const series = {};
  jobs.forEach((job, k) => {
    const byEpoch = new Map(metrics[k].map((m) => [m.epoch, m.val_loss ?? m.train_loss]));
    series[`${job.id} (${modelLabel(job)})`] = x.map((e) => byEpoch.get(e) ?? null);
  });
  const host = el("div", { id: "compare-chart", role: "img", "aria-label": "validation loss per epoch of each job" });
  view.append(el("div", { class: "card" }, el("h2", { text: "Validation loss" }), host));
  chart(host, { x, series, xLabel: "epoch", yLabel: "validation loss (log scale)", logY: true });
  const keys = [...new Set(jobs.flatMap((j) => Object.keys(j.training || {})))];
  const row = (label, f) => el("tr", {}, el("th", { scope: "row", text: label }), jobs.map((j, k) => el("td", {}, f(j, k))));
  view.append(el("h2", { text: "Settings and results" }), el("div", { class: "table-wrap" }, el("table", { id: "compare-table" },
    el("thead", {}, el("tr", {}, el("th", { scope: "col", text: "" }), jobs.map((j) => el("th", { scope: "col" }, el("a", { href: `#/jobs/${j.id}`, text: j.id }))))),
    el("tbody", {},
      row("model", (j) => modelLabel(j)),
      row("state", (j) => stateBadge(j.state)),
      row("dataset", (j) => datasetRef(j.dataset_id, names)),
      row("validation", (j) => (j.validation_dataset_id ? datasetRef(j.validation_dataset_id, names) : "held out")),
      keys.map((key) => row(key, (j) => String(j.training?.[key] ?? "–"))),
      row("epochs run", (j) => String(j.epoch)),
      row("best val loss", (j) => fmtBestLoss(j.best_val_loss, j.best_val_loss_steps)),
      row("final train loss", (j) => fmtLoss(j.train_loss)),
      row("duration", (j) => duration(j))))));
  // The trained models' median open-loop error on one dataset, a line each.
  const trained = jobs.filter((j) => j.model_id).map((j) => ({ id: j.model_id, label: `${j.id} (${modelLabel(j)})` }));
  if (!trained.length) return;
  const datasets = (await api("GET", "/v1/datasets?page_size=1000")).items;
  const dsSelect = el("select", { id: "compare-dataset" }, datasets.map((d) => el("option", { value: d.id, text: `${d.name || d.id} (${d.count} rows)` })));
  dsSelect.value = jobs[0].dataset_id;
  horizonPanel(view, trained, dsSelect, { controls: [el("label", { for: "compare-dataset", text: "Trajectories" }), dsSelect] });
}

