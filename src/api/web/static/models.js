// graybox dashboard, the models: the list (#/models) and one model (#/models/ID) with its
// error against horizon and its replay of recorded trajectories. Loaded before app.js,
// whose helpers (el, api, chart, …) these functions use when called.
"use strict";

async function modelsView(view) {
  const tbody = el("tbody");
  const empty = el("p", { class: "muted" });
  async function load() {
    const data = await api("GET", `/v1/models?page_size=${PAGE_SIZE}`);
    tbody.replaceChildren(...data.items.map((m) => el("tr", { "data-model": m.id },
      el("td", { class: "name" }, el("a", { href: `#/models/${m.id}`, text: m.name }), el("div", { class: "muted small", text: m.id })),
      el("td", { text: m.origin }),
      el("td", { class: "num", text: sizes(m) }), el("td", { class: "num", text: m.m }), el("td", { class: "num", text: m.dt }),
      el("td", { class: "num", text: fmtBestLoss(m.metrics?.best_val_loss, m.metrics?.best_val_loss_steps) }), timeCell(m.created_at))));
    empty.textContent = data.items.length ? "" : "No models yet: they appear when a job succeeds, or upload a model file.";
  }
  view.append(el("h1", { text: "Models" }), el("div", { class: "table-wrap" }, el("table", { id: "models-table" },
    el("thead", {}, el("tr", {}, ["model", "origin", "nq / nv", "m", "Δt", "best val loss", "created"].map((h, i) =>
      el("th", { scope: "col", class: i === 6 ? "hide-narrow" : undefined, text: h })))), tbody)),
  empty, modelUploadForm(load));
  await load();
}

// A model: what it is, what it learned, its error against horizon and its replay of recorded
// trajectories.
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
      ["nq / nv (configuration / velocities)", `${sizes(m)}: ${coordinateNames(m).join(", ")}`], ["m (inputs)", String(m.m)], ["Δt", `${m.dt} s`],
      [bestLossLabel(m.metrics?.best_val_loss_steps), fmtLoss(m.metrics?.best_val_loss)], ["epochs", String(m.metrics?.epochs ?? "–")],
      ["created", fmtTime(m.created_at)],
    ])),
    el("h2", { text: "Spec" }), specView(m.spec),
    physical.length ? [
      el("h2", { text: "Learned physical parameters" }),
      physicalTable(physical, m.metrics?.ensemble?.physical_parameters),
      identifiable.length ? [el("h3", { text: "Identifiable combinations" }), el("ul", {}, identifiable.map((c) => el("li", { text: `${c.name} = ${Number(c.value).toPrecision(6)}` })))] : "",
      m.identifiability ? el("p", { class: "muted", text: m.identifiability }) : "",
    ] : "",
    membersTable(m.metrics?.ensemble?.members), energyReport(m.metrics?.energy)].flat(Infinity));
  await replayPanel(view, m);
}

// The stored energy report in a sentence of its own figures (the worst rollout's drift beside
// the median's: one rollout far off is what a controller would meet), then drift and
// passivity in a table.
function energyReport(e) {
  if (!e) return "";
  const pct = (v) => (v === null || v === undefined ? "–" : `${(100 * v).toPrecision(2)} %`);
  const rows = [
    ...e.drift.map((d) => [`drift after ${d.steps} steps (${d.seconds} s), median / max`, `${pct(d.median)} / ${pct(d.max)}${d.diverged ? ` (${d.diverged} diverged)` : ""}`]),
    ["creates energy in", `${pct(e.passivity.share)} of ${e.passivity.states} states (largest power ${Number(e.passivity.max_power).toPrecision(3)})`],
    ["switched off in the rollouts", e.switched_off.length ? e.switched_off.join(", ") : "nothing (no part named damping or friction)"],
  ];
  return el("div", { class: "card", id: "model-energy" },
    el("h2", { text: "Energy" }), el("p", { id: "model-energy-summary", text: energySentence(e) }),
    el("p", { class: "muted", text: `Drift: unforced rollouts from ${e.rollouts} ${e.dataset_id ? `states of dataset ${e.dataset_id}` : "training states"}, |E(t) − E(0)| as a share of their mean kinetic energy plus the range of V. Creates energy: q̇ᵀF(q, q̇, 0) > 0.` }),
    el("div", { class: "table-wrap" }, el("table", { id: "model-energy-table" },
      el("tbody", {}, rows.map(([k, v]) => el("tr", {}, el("th", { scope: "row", text: k }), el("td", { text: v })))))));
}

// "The model creates energy in 12.0 % of states; unforced rollouts drift by 0.4 % (median) and
// up to 1.0e+4 % (the worst of 64) of the energy scale in 1000 steps": the median alone would
// hide the one rollout that runs away.
function energySentence(e) {
  const pct = (v) => {
    const p = 100 * v;
    return p >= 0.1 && p < 1000 ? `${p.toFixed(1)} %` : `${p.toExponential(1)} %`;
  };
  const p = e.passivity;
  const creates = p.injecting ? `creates energy in ${pct(p.share)} of states` : "never creates energy where it has data";
  const d = e.drift[e.drift.length - 1];
  let drifts = "";
  if (d && d.median !== null && d.median !== undefined) {
    const lost = d.diverged ? ` (${d.diverged} diverged)` : "";
    drifts = `; unforced rollouts drift by ${pct(d.median)} (median) and up to ${pct(d.max)} (the worst of ${e.rollouts}) ` +
      `of the energy scale in ${d.steps} steps${lost}`;
  } else if (d) {
    drifts = `; every unforced rollout diverged within ${d.steps} steps`;
  }
  return `The model ${creates}${drifts}.`;
}

// Energy along a replay (POST /v1/models/{id}/energy, a few hundred states a call: REST
// bodies are small): T, V, E and E(0) plus the work of F, whose gap is what the model
// creates or loses; and per coordinate the terms of M q̈ + c + ∇V = F with F's parts. A naive
// model has no energy: the charts say so instead.
async function energyCharts(m, r, dt, host) {
  const T = r.u.length;
  const x = (k) => [...r.predicted.q[k], ...r.predicted.qdot[k]];
  // The state at each step's start and at its end under that step's input, for the work.
  const rows = [...Array(T).keys()].flatMap((k) => [[x(k), r.u[k]], [x(k + 1), r.u[k]]]);
  const per = Math.max(2, 2 * Math.floor(20000 / (24 * (m.nq + m.nv + m.m))));
  const parts = [];
  for (let s = 0; s < rows.length; s += per) {
    const chunk = rows.slice(s, s + per);
    parts.push(await api("POST", `/v1/models/${m.id}/energy`, { x: chunk.map((c) => c[0]), u: chunk.map((c) => c[1]) }));
  }
  const all = (key) => parts.flatMap((p) => p[key]);
  const start = (key) => all(key).filter((_, i) => i % 2 === 0);
  const atStates = (key) => [...start(key), all(key)[2 * T - 1]];
  const power = all("power");
  const work = [0];
  for (let k = 0; k < T; k++) work.push(work[k] + (dt / 2) * (power[2 * k] + power[2 * k + 1]));
  const total = atStates("total");
  const energy = el("div", { id: "energy-chart", role: "img", "aria-label": "kinetic, potential and total energy, and the work of the forces, along the replay" });
  const figures = el("div", { class: "charts" }, el("figure", {}, el("figcaption", { text: "energy" }), energy));
  host.replaceChildren(el("h3", { text: "Energy along the replay" }),
    el("p", { class: "muted", text: "T, V (up to its constant) and E = T + V of the predicted states; E(0) plus the work of the generalized forces (trapezoid rule). Where the two part, the model itself creates or loses energy." }),
    figures);
  const units = coordinateUnits(m);
  chart(energy, {
    x: r.t, xLabel: "time (s)", yLabel: withUnit("energy", siUnits(m) ? "J" : null),
    series: { T: atStates("kinetic"), V: atStates("potential"), E: total, "E(0) + work of F": work.map((w) => total[0] + w) },
    dashed: ["E(0) + work of F"],
  });
  const names = coordinateNames(m);
  const named = parts[0].parts.map((p) => p.name);
  for (let i = 0; i < m.nv; i++) {
    const col = (key) => start(key).map((row) => row[i]);
    const series = { "M q̈": col("inertial"), "c (Coriolis)": col("coriolis"), "∇V (gravity)": col("gravity") };
    for (const name of named) {
      series[`F: ${name}`] = parts.flatMap((p) => p.parts.find((q) => q.name === name).values).filter((_, j) => j % 2 === 0).map((row) => row[i]);
    }
    const split = el("div", { class: "split-chart", "data-coordinate": String(i), role: "img", "aria-label": `terms of the dynamics of ${names[i]}` });
    figures.append(el("figure", {}, el("figcaption", { text: `${names[i]}: M q̈ + c + ∇V = F, term by term` }), split));
    chart(split, { x: r.t.slice(0, T), xLabel: "time (s)", yLabel: withUnit("generalized force", siUnits(m) ? forceUnit(units[i]) : null), series });
  }
}

// One value per parameter; an ensemble's members' mean with its bootstrap error bar (± one
// standard deviation across the members), drawn to scale beside it.
function physicalTable(physical, spread) {
  // One scale for every bar: the widest ± 3σ fills its cell.
  const rels = Object.values(spread || {}).map((s) => (s.mean ? s.std / Math.abs(s.mean) : 0));
  const scale = Math.max(1e-9, ...rels.map((r) => 3 * r));
  const head = spread
    ? ["parameter", "mean", "± σ", "σ / |mean|", `error bar: ± σ dark, ± 3σ light (half-width ${(100 * scale).toPrecision(2)} % of the mean)`]
    : ["parameter", "value"];
  const row = ([k, v]) => {
    const s = spread?.[k];
    if (!s) return el("tr", {}, el("td", { text: k }), el("td", { class: "num", text: Number(v).toPrecision(6) }));
    const rel = s.mean ? s.std / Math.abs(s.mean) : null;
    return el("tr", { "data-parameter": k }, el("td", { text: k }),
      el("td", { class: "num", text: Number(s.mean).toPrecision(6) }),
      el("td", { class: "num", text: Number(s.std).toPrecision(3) }),
      el("td", { class: "num", text: rel === null ? "–" : `${(100 * rel).toFixed(2)} %` }),
      el("td", {}, errorBar(rel, scale)));
  };
  return el("div", { class: "table-wrap" }, el("table", { id: "physical-table" },
    el("thead", {}, el("tr", {}, head.map((h) => el("th", { scope: "col", text: h })))),
    el("tbody", {}, physical.map(row))));
}

// A bar for ± σ (dark) inside ± 3σ (light) of σ / |mean| = `rel`, the cell's half-width
// being `scale` of the mean.
function errorBar(rel, scale) {
  if (rel === null) return "";
  const pct = (k) => Math.min(50, (50 * k * rel) / scale);
  const box = el("div", { class: "errorbar", title: `± ${(100 * rel).toFixed(2)} % of the mean` });
  // Through the style object: the Content-Security-Policy forbids style attributes.
  const span = (k) => {
    const e = el("span", { class: `errorbar-${k}` });
    e.style.left = `${50 - pct(k)}%`;
    e.style.width = `${2 * pct(k)}%`;
    return e;
  };
  box.append(span(3), span(1), el("span", { class: "errorbar-mean" }));
  return box;
}

// An ensemble's members: each one's best validation loss and epoch.
function membersTable(members) {
  if (!members?.length) return "";
  return [el("h2", { text: `Ensemble: ${members.length} members` }),
    el("p", { class: "muted", text: "Each member trained on its own bootstrap resample (or all the data) from its own seed; the service answers with their mean and spread." }),
    el("div", { class: "table-wrap" }, el("table", { id: "members-table" },
      el("thead", {}, el("tr", {}, ["member", "best epoch", "best val loss", "final train loss"].map((h) => el("th", { scope: "col", text: h })))),
      el("tbody", {}, members.map((r, k) => el("tr", {}, el("td", { text: String(k) }),
        el("td", { class: "num", text: String(r.best_epoch) }),
        el("td", { class: "num", text: fmtLoss(r.best_val_loss) }),
        el("td", { class: "num", text: fmtLoss(r.train_loss) }))))))];
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

// A state is [q, v]: nq configuration values and nv velocities (one number when they agree).
const sizes = (m) => (m.nq === m.nv ? String(m.nv) : `${m.nq} / ${m.nv}`);
const coordinateNames = (m) => m.coordinates || Array.from({ length: m.nv }, (_, i) => `q${i + 1}`);

// The dataset's trajectories a model can be rolled along (two steps or more), longest first;
// none for a dataset of independent transitions (`graybox simulate --count`, rows whose next
// state is no other row's state), whose every "trajectory" is a single step.
async function rolloutTrajectories(dataset) {
  const found = [];
  let token = "";
  do {
    const q = new URLSearchParams({ page_size: 1000 });
    if (token) q.set("page_token", token);
    const list = await api("GET", `/v1/datasets/${dataset.id}/trajectories?${q}`);
    // Each transition is in one trajectory: as many trajectories as transitions, all single.
    if (list.count >= dataset.count) return [];
    found.push(...list.items.filter((t) => t.length > 1));
    token = list.next_page_token;
  } while (token && !found.length);
  return found.sort((a, b) => b.length - a.length);
}

async function replayPanel(view, m) {
  const names = coordinateNames(m);
  const units = coordinateUnits(m);
  const configuration = m.configuration ? m.configuration.map((c) => [c, units[names.indexOf(c)] ?? null]) : names.map((c, i) => [c, units[i]]);
  // An ensemble replays as one particle per member too: their spread is the band.
  const members = m.metrics?.ensemble?.members?.length ?? 1;
  const datasets = (await api("GET", "/v1/datasets?page_size=1000")).items.filter((d) => d.nq === m.nq && d.nv === m.nv && d.m === m.m);
  const dsSelect = el("select", { id: "replay-dataset" }, datasets.map((d) => el("option", { value: d.id, text: `${d.name || d.id} (${d.count} rows)` })));
  // First the data its training held out, else the data it trained on (the newest dataset
  // may have nothing to do with this model).
  const job = m.job_id ? await api("GET", `/v1/jobs/${m.job_id}`).catch(() => null) : null;
  const own = [job?.validation_dataset_id, job?.dataset_id].find((id) => datasets.some((d) => d.id === id));
  if (own) dsSelect.value = own;
  const trLabel = el("label", { for: "replay-index", text: "Trajectory" });
  const trSelect = el("select", { id: "replay-index" });
  const status = el("div", { role: "alert", id: "replay-alert" });
  const note = el("p", { class: "note", role: "status", id: "replay-note" });
  const charts = el("div", { class: "charts", id: "replay-charts" });
  const spreadNote = el("p", { class: "muted", id: "replay-spread-note" });
  const energy = el("div", { id: "replay-energy" });
  const go = el("button", { type: "button", id: "replay-button" }, "Replay");
  view.append(el("h2", { text: "Rollout against data" }), el("p", { class: "muted",
    text: "The model predicts a recorded trajectory from its first state with its recorded inputs; recorded and predicted q and q̇ over time." }));
  if (!datasets.length) {
    view.append(el("p", { text: `No dataset with nq = ${m.nq}, nv = ${m.nv}, m = ${m.m}.` }));
    horizonPanel(view, [], null, { stored: m.metrics?.horizon_errors, unit: sharedUnit(units) });
    return;
  }
  view.append(el("div", { class: "toolbar" },
    el("label", { for: "replay-dataset", text: "Dataset" }), dsSelect, trLabel, trSelect, go), note, status, spreadNote, charts, energy);
  const evaluate = horizonPanel(view, [{ id: m.id, label: m.id }], dsSelect, { stored: m.metrics?.horizon_errors, unit: sharedUnit(units) });

  // Trajectories to choose from, or, for independent transitions, why there are none.
  async function loadTrajectories() {
    const d = datasets.find((x) => x.id === dsSelect.value);
    const items = await rolloutTrajectories(d);
    if (dsSelect.value !== d.id) return false; // another dataset was chosen meanwhile
    trSelect.replaceChildren(...items.map((t) => el("option", { value: t.index, text: `#${t.index} (${t.length} steps)` })));
    const usable = items.length > 0;
    for (const e of [trLabel, trSelect, go, spreadNote, charts, energy]) e.hidden = !usable;
    evaluate.disabled = !usable;
    if (!usable) {
      charts.replaceChildren();
      energy.replaceChildren();
    }
    note.textContent = usable ? "" : `The dataset “${d.name || d.id}” holds independent transitions, not trajectories: each of its ` +
      `${d.count} transitions starts from its own state, so the model has nothing to be rolled along. Rollouts need ` +
      "trajectories: upload the data as trajectories (a dataset file in the trajectory form, or rows in time order " +
      "whose next state is the following row's state) to replay it or evaluate the model's error against horizon.";
    return usable;
  }
  async function replay() {
    status.replaceChildren();
    try {
      const particles = members > 1 ? `&particles=${members}` : "";
      const r = await api("GET", `/v1/models/${m.id}/rollout?dataset_id=${encodeURIComponent(dsSelect.value)}&index=${trSelect.value}${particles}`);
      charts.replaceChildren();
      const spread = r.particles;
      spreadNote.textContent = spread ? `Shaded: the mean ± σ of ${spread.count} particles, one per member, each rolled out ` +
        "on its member alone; “predicted” is the mean dynamics, what the service serves." : "";
      for (const key of ["q", "qdot"]) {
        for (let i = 0; i < (key === "q" ? m.nq : m.nv); i++) {
          // Coordinates by their names: a URDF's joints, a formula's coordinates; q's values
          // by theirs where a rotation keeps two (cos θ, sin θ, without a unit).
          const label = key === "q" ? configuration[i][0] : `${names[i]} rate`;
          const unit = key === "q" ? configuration[i][1] : rateUnit(units[i]);
          const host = el("div", { class: "replay-chart", "data-variable": `${key}${i}`, role: "img", "aria-label": `${label}, recorded and predicted` });
          charts.append(el("figure", {}, el("figcaption", { text: label }), host));
          const series = { recorded: r.recorded[key].map((row) => row[i]), predicted: r.predicted[key].map((row) => row[i]) };
          const bands = [];
          if (spread) {
            // Rows stop where a particle left the finite numbers: the band stops there.
            const column = (s) => r.t.map((_, k) => s[key][k]?.[i] ?? null);
            const [mean, std] = [column(spread.mean), column(spread.std)];
            const edge = (sign) => mean.map((v, k) => (v === null || std[k] === null ? null : v + sign * std[k]));
            Object.assign(series, { "members' mean": mean, "members' mean + σ": edge(1), "members' mean − σ": edge(-1) });
            bands.push({ of: "members' mean", upper: "members' mean + σ", lower: "members' mean − σ" });
          }
          chart(host, { x: r.t, xLabel: "time (s)", yLabel: withUnit(label, unit), dashed: ["predicted"], series, bands });
        }
      }
      if (m.spec?.kind === "naive") {
        energy.replaceChildren(el("p", { class: "muted", id: "energy-note", text: "A naive model predicts q̈ directly: it has no mass matrix, potential or forces to read energy from." }));
      } else {
        await energyCharts(m, r, r.dt, energy);
      }
    } catch (e) {
      status.replaceChildren(errorBox(e));
    }
  }
  async function show() {
    status.replaceChildren();
    try {
      if (await loadTrajectories()) await replay();
    } catch (e) {
      status.replaceChildren(errorBox(e));
    }
  }
  dsSelect.addEventListener("change", show);
  go.addEventListener("click", replay);
  await show();
}

// Open-loop error against prediction time, both axes logarithmic: first what the training
// measured on its validation trajectories (`stored`, a model's metrics.horizon_errors), then,
// on request, on the chosen dataset's trajectories (POST /v1/models/{id}/evaluate): one
// model's median and mean, or each compared model's median. `models`: [{id, label}]; without
// `dsSelect`, the stored figures alone. Returns the Evaluate button.
function horizonPanel(view, models, dsSelect, { controls = [], stored = [], unit = null } = {}) {
  view.append(el("h2", { text: "Error against horizon" }));
  const yLabel = unit ? `|q̂ − q| (${unit}, log scale)` : "|q̂ − q| (log scale)";
  if (stored?.length) storedHorizonErrors(view, stored, yLabel);
  if (!dsSelect) return null;
  const horizons = [1, 2, 5, 10, 20, 50, 100, 200, 500];
  const host = el("div", { id: "horizon-chart", role: "img", "aria-label": "open-loop error against prediction time" });
  const status = el("div", { role: "alert", id: "horizon-alert" });
  const go = el("button", { type: "button", id: "horizon-button" }, "Evaluate");
  view.append(el("p", { class: "muted",
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
        x: items[0].map((e) => e.seconds), xLabel: "prediction time (s)", yLabel,
        logX: true, logY: true, series,
      });
    } catch (e) {
      status.replaceChildren(errorBox(e));
    }
  });
  return go;
}

// The stored errors as they are: a chart of q's median and mean, and every figure in a table.
function storedHorizonErrors(view, errors, yLabel) {
  const host = el("div", { id: "model-horizon-chart", role: "img",
    "aria-label": "open-loop error against prediction time on the validation trajectories, at the end of training" });
  const columns = [["horizon", "steps"], ["seconds", "time (s)"], ["windows", "windows"], ["diverged", "diverged"],
    ["position_median", "|q̂ − q| median"], ["position_mean", "|q̂ − q| mean"],
    ["velocity_median", "|q̂̇ − q̇| median"], ["velocity_mean", "|q̂̇ − q̇| mean"]];
  // Counts as they are; errors to 4 digits (null: no windows, or an infinite error).
  const fmt = (v) => (v === null || v === undefined ? "–" : Number.isInteger(v) ? String(v) : Number(v).toPrecision(4));
  const table = el("table", { id: "model-horizon-table" },
    el("caption", { class: "muted", text: "Error after each horizon, from every state of the validation trajectories" }),
    el("thead", {}, el("tr", {}, columns.map(([, h]) => el("th", { scope: "col", text: h })))),
    el("tbody", {}, errors.map((e) => el("tr", { "data-horizon": e.horizon },
      columns.map(([k]) => el("td", { class: "num", text: fmt(e[k]) }))))));
  view.append(el("div", { class: "card", id: "model-horizon" },
    el("h3", { text: "At the end of training, on the validation trajectories" }), host,
    el("div", { class: "table-wrap" }, table)));
  chart(host, {
    x: errors.map((e) => e.seconds), xLabel: "prediction time (s)", yLabel, logX: true, logY: true,
    series: { median: errors.map((e) => e.position_median), mean: errors.map((e) => e.position_mean) },
  });
}
