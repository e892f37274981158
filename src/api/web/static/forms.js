// graybox dashboard, the forms that change things: a new job (#/new), model and template
// uploads, and delete buttons (the API's 409 shown when the item is still in use). Loaded
// before app.js, whose helpers (el, api, errorBox, …) these functions use when called.
"use strict";

// ---------- fields and their errors ----------

// A labelled input with the slot where an API error naming `name` appears.
function field(name, id, label, input, hint) {
  return el("div", { class: "field", "data-field": name },
    el("label", { for: id, text: label }), input,
    hint ? el("div", { class: "muted small", text: hint }) : "",
    el("div", { class: "field-error", role: "alert", "data-error-for": name }));
}

// Shows `err` beside the field it names, or the nearest enclosing one ("training.lr" →
// "training.lr"; "template.params[0]" → "template"), else in `fallback`.
function showError(form, err, fallback) {
  clearErrors(form, fallback);
  let name = err.field || "";
  while (name) {
    const slot = form.querySelector(`[data-error-for="${CSS.escape(name)}"]`);
    if (slot) {
      slot.textContent = err.field === name ? err.message : `${err.field}: ${err.message}`;
      slot.closest(".field").querySelector("input, select, textarea")?.focus();
      return;
    }
    // One segment off the end; a name with none left to take (an API field the form has no
    // place for, such as "body") ends the search instead of being tried forever.
    const shorter = name.replace(/(\.[^.[]*|\[[^\]]*\])$/, "");
    name = shorter === name ? "" : shorter;
  }
  fallback.replaceChildren(errorBox(err.field ? `${err.field}: ${err.message}` : err));
}

function clearErrors(form, fallback) {
  for (const slot of form.querySelectorAll("[data-error-for]")) slot.replaceChildren();
  fallback.replaceChildren();
}

// A local check's error, shaped as the API's.
const fieldErr = (field, message) => Object.assign(new Error(message), { field });

// ---------- deleting ----------

// A button that deletes `path` after the person confirms; the API's refusal (409 while a job
// or model uses the item) goes to `status`.
function deleteButton(path, what, status, onDeleted) {
  return el("button", { type: "button", class: "secondary danger", "data-delete": path, onclick: async (e) => {
    if (!confirm(`Delete ${what}? This cannot be undone.`)) return;
    e.target.disabled = true;
    status.replaceChildren();
    try {
      await api("DELETE", path);
      await onDeleted();
    } catch (err) {
      status.replaceChildren(errorBox(err));
      e.target.disabled = false;
    }
  } }, "Delete");
}

// ---------- a new job ----------

const TRAINING_HINTS = {
  epochs: "passes over the training data",
  batch_size: "transitions per step (windows, when horizon > 1)",
  lr: "Adam's learning rate",
  lambda: "weight of the velocity error in the loss",
  val_fraction: "share held out for validation when no validation dataset is chosen",
  seed: "initial weights, shuffling and the held-out split",
  integrator: "the integrator the model steps with",
  patience: "stop after this many epochs without a better validation loss (empty: never)",
  horizon: "transitions per training window (1: the one-step loss)",
  discount: "weight γ of each further step of a window",
  one_step_epochs: "epochs on the one-step loss before the windows",
  window_lr: "learning rate of the epochs on windows",
};
// What an empty field means, for the fields without a value by default.
const EMPTY_MEANS = { patience: "off", window_lr: "lr" };

async function newJobView(view) {
  const [datasets, templates] = await Promise.all([
    api("GET", "/v1/datasets?page_size=1000").then((d) => d.items),
    api("GET", "/v1/templates?page_size=1000").then((d) => d.items),
  ]);
  view.append(el("h1", { text: "New job" }));
  if (!datasets.length) {
    view.append(el("p", {}, "No datasets yet: ", el("a", { href: "#/datasets", text: "upload one" }), " first."));
    return;
  }
  const D = GRAYBOX_DEFAULTS;
  const dsLabel = (d) => `${d.name || d.id} (${widths(d)}, m = ${d.m}, ${d.count} rows)`;
  const name = el("input", { type: "text", id: "job-name", placeholder: "optional: the model's name" });
  const dataset = el("select", { id: "job-dataset" }, datasets.map((d) => el("option", { value: d.id, text: dsLabel(d) })));
  const validation = el("select", { id: "job-validation" }, el("option", { value: "", text: "none: hold out val_fraction of the dataset" }),
    datasets.map((d) => el("option", { value: d.id, text: dsLabel(d) })));
  const model = el("select", { id: "job-model" }, D.models.map((m) => el("option", { value: m, text: m })),
    el("option", { value: "spec", text: "a spec of my own (JSON)" }));
  const spec = el("textarea", { id: "job-spec", rows: 6, placeholder: '{"kind": "structured", …}' });
  const template = el("select", { id: "job-template" },
    el("option", { value: "", text: "none (a naive model needs none)" }),
    el("optgroup", { label: "built in" }, D.templates.map((t) => el("option", { value: t, text: t }))),
    templates.length ? el("optgroup", { label: "stored" }, templates.map((t) => el("option", { value: t.id, text: `${t.name} (${t.kind}, n = ${t.n}, m = ${t.m})` }))) : "",
    el("option", { value: "file", text: "upload a file (URDF or formula JSON)…" }));
  const templateFile = el("input", { type: "file", id: "job-template-file", accept: ".urdf,.xml,.json" });
  const training = {};
  const trainingFields = Object.keys(TRAINING_HINTS).filter((k) => k in D.training).map((k) => {
    const v = D.training[k];
    const id = `job-${k.replace(/_/g, "-")}`;
    training[k] = k === "integrator"
      ? el("select", { id }, D.integrators.map((i) => el("option", { value: i, text: i, selected: i === v })))
      : el("input", { type: "number", id, step: "any", value: v ?? "", placeholder: v === null ? EMPTY_MEANS[k] : undefined });
    return field(`training.${k}`, id, k, training[k], `${TRAINING_HINTS[k]} (default ${v ?? EMPTY_MEANS[k]})`);
  });
  const alert = el("div", { role: "alert", id: "job-form-alert" });
  const submit = el("button", { type: "submit" }, "Start training");
  const specField = field("model", "job-spec", "Model spec", spec, "README \"Model specs\": mass, potential and forces, each a network or the template's");
  const fileField = field("template", "job-template-file", "Template file", templateFile, "a URDF (.urdf, .xml) or a formula template (.json), stored as a template");
  const sync = () => { specField.hidden = model.value !== "spec"; fileField.hidden = template.value !== "file"; };
  model.addEventListener("change", sync);
  template.addEventListener("change", sync);
  sync();
  const form = el("form", { id: "job-form", class: "card" },
    el("div", { class: "form-grid" },
      field("name", "job-name", "Name", name),
      field("dataset_id", "job-dataset", "Dataset", dataset),
      field("validation_dataset_id", "job-validation", "Validation dataset", validation),
      field("model", "job-model", "Model", model, "a letter is a network (M mass, V potential, F forces, B input matrix); W-B is all white-box"),
      specField,
      field("template", "job-template", "Template", template, "the white-box parts and their physical parameters"),
      fileField),
    el("h2", { text: "Training" }),
    el("div", { class: "form-grid" }, trainingFields),
    el("div", { class: "toolbar" }, submit), alert);
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clearErrors(form, alert);
    submit.disabled = true;
    try {
      const job = await api("POST", "/v1/jobs", await jobRequest());
      location.hash = `#/jobs/${job.id}`;
    } catch (err) {
      showError(form, err, alert);
    } finally {
      submit.disabled = false;
    }
  });
  view.append(form);

  // The request as the API takes it; a template file is stored first and named by its id.
  async function jobRequest() {
    const body = { dataset_id: dataset.value, training: {} };
    if (name.value.trim()) body.name = name.value.trim();
    if (validation.value) body.validation_dataset_id = validation.value;
    if (model.value === "spec") {
      try { body.model = JSON.parse(spec.value); } catch (err) { throw fieldErr("model", `is not JSON: ${err.message}`); }
    } else body.model = model.value;
    for (const [k, input] of Object.entries(training)) {
      if (input.value === "") continue; // patience off, window_lr = lr
      body.training[k] = k === "integrator" ? input.value : Number(input.value);
    }
    if (template.value === "file") body.template = await storeTemplate(templateFile.files[0]);
    else if (template.value) body.template = template.value;
    return body;
  }
}

// A template file's content type: a URDF is XML, a formula template JSON.
const templateType = (file) => (/\.(urdf|xml)$/i.test(file.name) ? "application/xml" : "application/json");

// Stores a template file (POST /v1/templates) and returns its id; its errors name `template`.
async function storeTemplate(file) {
  if (!file) throw fieldErr("template", "choose a URDF or formula template file");
  try {
    return (await api("POST", "/v1/templates", file, templateType(file))).id;
  } catch (err) {
    throw fieldErr(err.field ? `template.${err.field}` : "template", err.message);
  }
}

// ---------- uploads of models and templates ----------

// A form that uploads one file to `path` (with an optional name) and reports what it stored.
function uploadForm({ id, title, accept, fileLabel, contentType, path, withName, onDone }) {
  const file = el("input", { type: "file", id: `${id}-file`, accept, required: true });
  const name = el("input", { type: "text", id: `${id}-name`, placeholder: "optional" });
  const alert = el("div", { role: "alert", id: `${id}-alert` });
  const status = el("p", { class: "muted", "aria-live": "polite", id: `${id}-status` });
  const form = el("form", { class: "stack card", id },
    el("h2", { text: title }),
    field("file", `${id}-file`, fileLabel, file),
    withName ? field("name", `${id}-name`, "Name", name) : "",
    el("div", {}, el("button", { type: "submit" }, "Upload")), alert, status);
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clearErrors(form, alert);
    status.textContent = "";
    const f = file.files[0];
    if (!f) { showError(form, fieldErr("file", "choose a file first"), alert); return; }
    const q = withName && name.value.trim() ? `?${new URLSearchParams({ name: name.value.trim() })}` : "";
    try {
      const item = await api("POST", path + q, f, contentType(f));
      status.textContent = `Stored as ${item.id}${item.created === false ? " (uploaded before)" : ""}.`;
      form.reset();
      await onDone(item);
    } catch (err) {
      showError(form, err, alert);
    }
  });
  return form;
}

function modelUploadForm(onDone) {
  return uploadForm({
    id: "model-upload", title: "Upload a model file", accept: ".gbx", fileLabel: "Model file (.gbx, from graybox train or a download)",
    contentType: () => "application/octet-stream", path: "/v1/models", withName: true, onDone,
  });
}

// Stored templates: a URDF or formula document each, usable by any job; delete when unused.
async function templatesView(view) {
  const tbody = el("tbody");
  const status = el("div", { role: "alert", id: "templates-alert" });
  async function load() {
    const items = (await api("GET", "/v1/templates?page_size=1000")).items;
    tbody.replaceChildren(...items.map((t) => el("tr", { "data-template": t.id },
      el("td", { class: "name" }, t.name, el("div", { class: "muted small", text: t.id })),
      el("td", { text: t.kind }), el("td", { class: "num", text: t.n }), el("td", { class: "num", text: t.m }),
      el("td", { class: "wrap", text: t.coordinates.join(", ") }),
      timeCell(t.created_at),
      el("td", {}, deleteButton(`/v1/templates/${t.id}`, `template ${t.name}`, status, load)))));
    if (!items.length) tbody.append(el("tr", {}, el("td", { colspan: 7, class: "muted", text: "No stored templates: upload a URDF or a formula template." })));
  }
  view.append(el("h1", { text: "Templates" }),
    uploadForm({
      id: "template-upload", title: "Upload a template", accept: ".urdf,.xml,.json", fileLabel: "URDF (.urdf, .xml) or formula template (.json)",
      contentType: templateType, path: "/v1/templates", withName: false, onDone: load,
    }),
    status,
    el("div", { class: "table-wrap" }, el("table", { id: "templates-table" },
      el("thead", {}, el("tr", {}, ["template", "kind", "n", "m", "coordinates", "created", ""].map((h, i) =>
        el("th", { scope: "col", class: i === 5 ? "hide-narrow" : undefined, text: h })))), tbody)));
  await load();
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
      el("td", { class: "num", text: d.nq === d.nv ? String(d.nv) : `${d.nq} / ${d.nv}` }), el("td", { class: "num", text: d.m }),
      el("td", { class: "num", text: d.count }), el("td", { class: "num", text: d.dt }),
      el("td", { class: "num", text: `${((d.count * (2 * (d.nq + d.nv) + d.m) * 8) / 1024).toFixed(1)} KiB` }),
      el("td", { class: "wrap" }, d.warnings?.length ? el("details", { class: "warnings" },
        el("summary", { text: `⚠ ${d.warnings.length} warning${d.warnings.length > 1 ? "s" : ""}` }),
        el("ul", {}, d.warnings.map((w) => el("li", { text: `${w.field ? `${w.field}: ` : ""}${w.message}` })))) : "–"),
      timeCell(d.created_at),
      el("td", {}, deleteButton(`/v1/datasets/${d.id}`, `dataset ${d.name || d.id}`, listStatus, load)))));
  }
  view.append(el("h1", { text: "Datasets" }), form, listStatus, el("div", { class: "table-wrap" }, el("table", { id: "datasets-table" },
    el("thead", {}, el("tr", {}, ["dataset", "nq / nv", "m", "count", "Δt", "size", "warnings", "created", ""].map((h, i) => el("th", { scope: "col", class: i === 7 ? "hide-narrow" : undefined, text: h })))),
    tbody)));
  await load();
}

// A dataset's widths: n when q and qdot agree, else nq and nv.
function widths(d) {
  return d.nq === d.nv ? `n = ${d.nv}` : `nq = ${d.nq}, nv = ${d.nv}`;
}
