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
  if (params.get("offset")) query.set("offset", params.get("offset"));
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
    const summary = document.getElementById("summary");
    summary.replaceChildren(list.total === list.runs.length
      ? list.total + " run(s)"
      : "runs " + (list.offset + 1) + " to " + (list.offset + list.runs.length) + " of " + list.total + " ");
    const page = (offset, text) => {
      const q = new URLSearchParams(location.search);
      q.set("offset", offset);
      summary.append(element("a", text, { href: "/index.html?" + q.toString() }), document.createTextNode(" "));
    };
    if (list.offset > 0) page(Math.max(0, list.offset - list.limit), "previous");
    if (list.offset + list.runs.length < list.total) page(list.offset + list.limit, "next");
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
    if (run.status === "running") {
      document.getElementById("downloads").append(element("a", "Watch it live", { href: "/live.html?id=" + id }),
                                                  document.createTextNode(" "));
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

// A run as it is recorded: the server pushes the run, every capture as it is committed, events
// and progress over a WebSocket, and closes it when the run ends.
function livePage() {
  const id = new URLSearchParams(location.search).get("id");
  const captures = [];
  const plot = document.getElementById("plot");
  const body = document.querySelector("#captures tbody");
  let unit = "";
  const draw = () => {
    // Deviation against target, every capture, scaled to what has arrived.
    const xs = captures.map(c => c.target_mm), ys = captures.map(c => c.deviation);
    const x0 = Math.min(...xs), x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
    const px = x => 40 + (x1 > x0 ? (x - x0) / (x1 - x0) : 0.5) * 740;
    const py = y => 280 - (y1 > y0 ? (y - y0) / (y1 - y0) : 0.5) * 260;
    plot.replaceChildren();
    for (const c of captures) {
      const dot = document.createElementNS("http://www.w3.org/2000/svg", "circle");
      dot.setAttribute("cx", px(c.target_mm).toFixed(1));
      dot.setAttribute("cy", py(c.deviation).toFixed(1));
      dot.setAttribute("r", "3");
      dot.setAttribute("fill", c.direction === "up" ? "#1f5fa8" : "#c0392b");
      const tip = document.createElementNS("http://www.w3.org/2000/svg", "title");
      tip.textContent = c.target_mm.toFixed(3) + " mm: " + c.deviation.toFixed(2) + " " + unit;
      dot.append(tip);
      plot.append(dot);
    }
  };
  const scheme = location.protocol === "https:" ? "wss://" : "ws://";
  const socket = new WebSocket(scheme + location.host + "/api/live/" + encodeURIComponent(id));
  socket.onmessage = (message) => {
    const m = JSON.parse(message.data);
    if (m.type === "run") {
      unit = m.run.kind === "linear" ? "µm" : "";
      document.title = "mtcal: live run " + id;
      document.getElementById("title").textContent = "Run " + id + ": " + m.run.name;
    } else if (m.type === "capture") {
      captures.push(m);
      const row = element("tr", null, { "data-seq": m.seq });
      row.append(element("td", m.seq, { class: "num" }), element("td", m.target_mm.toFixed(3), { class: "num" }),
                 element("td", m.direction), element("td", m.cycle, { class: "num" }),
                 element("td", m.deviation.toFixed(2) + " " + unit, { class: "num" }));
      body.prepend(row);
      draw();
    } else if (m.type === "event") {
      const row = element("tr");
      row.append(element("td", m.time), element("td", m.level), element("td", m.message));
      document.querySelector("#events tbody").append(row);
    } else if (m.type === "progress") {
      const bar = document.getElementById("progress");
      bar.max = Math.max(1, m.planned || m.captures);
      bar.value = m.captures;
      const eta = m.eta_s === null ? "" : ", about " + Math.ceil(m.eta_s) + " s left";
      document.getElementById("progress-text").textContent =
        m.status + ": " + m.captures + (m.planned ? " of " + m.planned : "") + " captures" + eta;
      document.body.dataset.status = m.status;
    } else if (m.type === "error") {
      document.getElementById("progress-text").textContent = m.error;
      document.body.dataset.status = "error";
    }
  };
}

document.addEventListener("DOMContentLoaded", () => {
  status().catch(() => {});
  if (document.body.dataset.page === "archive") archivePage();
  if (document.body.dataset.page === "run") runPage();
  if (document.body.dataset.page === "live") livePage();
});
