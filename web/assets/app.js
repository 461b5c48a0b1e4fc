// The dashboard's pages: plain DOM, the archive's JSON from /api. No library, no other host.
"use strict";

function element(tag, text, attributes) {
  const e = document.createElement(tag);
  if (text !== undefined && text !== null) e.textContent = String(text);
  for (const [k, v] of Object.entries(attributes || {})) e.setAttribute(k, v);
  return e;
}

async function getJson(path) {
  const response = await fetch(path, { credentials: "same-origin" });
  const body = await response.json();
  if (!response.ok) throw new Error(body.error || response.statusText);
  return body;
}

function showError(where, error) {
  where.replaceChildren(element("p", String(error.message || error), { class: "error" }));
}

async function status() {
  const s = await getJson("/api/status");
  document.getElementById("archive-name").textContent =
    s.archive + (s.read_only ? " (read-only)" : "") + " · mtcal " + s.version;
}

async function archivePage() {
  const form = document.getElementById("filter");
  const params = new URLSearchParams(location.search);
  for (const [k, v] of params) if (form.elements[k]) form.elements[k].value = v;
  const query = new URLSearchParams();
  for (const e of form.elements) if (e.name && e.value) query.set(e.name, e.value);
  const body = document.querySelector("#runs tbody");
  try {
    const list = await getJson("/api/runs?" + query.toString());
    body.replaceChildren();
    for (const r of list.runs) {
      const row = element("tr", null, { "data-run": r.id });
      const link = element("a", r.id, { href: "/run.html?id=" + r.id });
      const first = element("td");
      first.append(link);
      row.append(first, element("td", r.name), element("td", r.machine), element("td", "c" + r.campaign_id),
                 element("td", r.kind), element("td", r.axis), element("td", r.status),
                 element("td", (r.started_at || "").replace("T", " ").replace(/\.\d+Z$/, "")),
                 element("td", r.measured + " " + (r.measured_unit || ""), { class: "num" }));
      body.append(row);
    }
    document.getElementById("summary").textContent = list.runs.length + " run(s)";
  } catch (error) {
    showError(document.getElementById("summary"), error);
  }
}

async function runPage() {
  const id = new URLSearchParams(location.search).get("id");
  try {
    const d = await getJson("/api/runs/" + encodeURIComponent(id));
    const run = d.run || d;
    document.title = "mtcal: run " + id;
    document.getElementById("title").textContent = "Run " + id + ": " + (run.name || "");
    const facts = document.getElementById("facts");
    for (const key of ["machine", "kind", "axis", "status", "started_at", "finished_at", "operator"]) {
      if (run[key] === undefined || run[key] === null || run[key] === "") continue;
      const row = element("tr");
      row.append(element("th", key.replace("_", " ")), element("td", run[key]));
      facts.append(row);
    }
    const events = document.querySelector("#events tbody");
    for (const e of d.events || []) {
      const row = element("tr");
      row.append(element("td", e.time), element("td", e.level), element("td", e.message));
      events.append(row);
    }
    const results = document.querySelector("#results tbody");
    for (const r of d.results || []) {
      const row = element("tr");
      row.append(element("td", r.processor), element("td", r.created_at));
      results.append(row);
    }
    const frame = document.getElementById("report");
    if (run.kind === "linear" || run.kind === "circle") {
      frame.src = "/api/runs/" + id + "/report.html";
      const download = element("a", "Download the report (HTML)",
                               { href: "/api/runs/" + id + "/report.html", download: "run-" + id + "-report.html" });
      document.getElementById("downloads").append(download);
    } else {
      frame.remove();
      document.getElementById("no-report").textContent =
        "Reports are made of linear and circle runs so far; this run's analyses: mtcal analyze.";
    }
  } catch (error) {
    showError(document.getElementById("facts"), error);
  }
}

document.addEventListener("DOMContentLoaded", () => {
  status().catch(() => {});
  if (document.body.dataset.page === "archive") archivePage();
  if (document.body.dataset.page === "run") runPage();
});
