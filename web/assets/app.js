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
  const start = document.getElementById("start-link");
  if (start && !s.read_only) start.hidden = false;
}

// A request that changes state: JSON, with the header the server asks of its own pages.
async function post(path, body) {
  const response = await fetch(path, {
    method: "POST", credentials: "same-origin",
    headers: { "Content-Type": "application/json", "X-Mtcal-Request": "1" }, body: JSON.stringify(body)
  });
  const answer = await response.json();
  if (!response.ok) throw new Error(answer.error || response.statusText);
  return answer;
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
      // Machines, then their campaigns, then runs: each a filter of the archive.
      const machine = element("td");
      machine.append(element("a", r.machine, { href: "/index.html?machine=" + encodeURIComponent(r.machine) }));
      const campaign = element("td");
      campaign.append(element("a", "c" + r.campaign_id, { href: "/index.html?campaign=c" + r.campaign_id,
                                                          title: "the campaign's runs" }),
                      document.createTextNode(" "),
                      element("a", "report", { href: "/api/campaigns/" + r.campaign_id + "/report.html",
                                               title: "the campaign's report" }));
      row.append(first, element("td", r.name), machine, campaign,
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
    const models = document.querySelector("#models tbody");
    for (const m of (await getJson("/api/models")).models) {
      const row = element("tr", null, { "data-model": m.id });
      const report = element("td");
      report.append(element("a", "report", { href: "/api/models/" + m.id + "/report.html" }));
      row.append(element("td", "m" + m.id), element("td", m.name), element("td", m.method),
                 element("td", (m.created_at || "").replace("T", " ").replace(/\.\d+Z$/, "")), report);
      models.append(row);
    }
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
    const downloads = document.getElementById("downloads");
    const link = (text, href, name) => {
      downloads.append(element("a", text, name ? { href: href, download: name } : { href: href }),
                       document.createTextNode(" "));
    };
    const frame = document.getElementById("report");
    if (run.status === "running") {
      frame.remove();
      document.getElementById("no-report").textContent = "The report is made when the run has ended.";
    } else {
      frame.addEventListener("load", () => {
        if (frame.contentDocument) frame.contentDocument.querySelectorAll("svg").forEach(zoomable);
      });
      frame.src = "/api/runs/" + id + "/report.html";
      link("Report (HTML)", "/api/runs/" + id + "/report.html", "run" + id + "_report.html");
      link("Report (PDF)", "/api/runs/" + id + "/report.pdf");
    }
    const files = document.getElementById("files");
    for (const f of (await getJson("/api/runs/" + id + "/files")).files) {
      const item = element("li");
      item.append(element("a", f.file, { href: "/api/runs/" + id + "/files/" + f.name, download: f.file }),
                  document.createTextNode(": " + f.what));
      files.append(item);
    }
    if (run.kind === "linear" && run.status !== "running") {
      // A compensation table of the run for the chosen controller (docs/compensation.md).
      const section = document.getElementById("compensation");
      const choice = element("select", null, { name: "controller" });
      for (const c of (await getJson("/api/status")).controllers) choice.append(element("option", c));
      const interval = element("input", null, { name: "interval", size: 5, placeholder: "targets" });
      const mean = element("input", null, { name: "mean", type: "checkbox" });
      const table = element("a", "Download the table", { id: "compensation-link" });
      const point = () => {
        const q = new URLSearchParams({ controller: choice.value });
        if (interval.value) q.set("interval", interval.value);
        if (mean.checked) q.set("mean", "");
        table.setAttribute("href", "/api/runs/" + id + "/compensation?" + q.toString());
      };
      for (const input of [choice, interval, mean]) input.addEventListener("input", point);
      point();
      const label = (text, input) => {
        const l = element("label", text + " ");
        l.append(input);
        return l;
      };
      section.append(document.createTextNode("Compensation table for "), choice, document.createTextNode(" "),
                     label("interval (mm)", interval), document.createTextNode(" "),
                     label("one table for both directions", mean), document.createTextNode(" "), table);
      const compare = document.getElementById("compare");
      compare.hidden = false;
      compare.elements.before.value = id;
    }
  } catch (error) {
    showError(document.getElementById("facts"), error);
  }
}

// Zoom and pan on a plot, as a magnifier: the wheel zooms about the pointer, dragging moves,
// a double click restores the whole plot. The values stay on hover.
function zoomable(svg) {
  const whole = svg.viewBox.baseVal;
  if (!whole || !whole.width) return;
  const initial = [whole.x, whole.y, whole.width, whole.height];
  let view = initial.slice();
  const show = () => svg.setAttribute("viewBox", view.map(v => v.toFixed(2)).join(" "));
  const at = event => {
    const box = svg.getBoundingClientRect();
    return [view[0] + (event.clientX - box.left) / box.width * view[2],
            view[1] + (event.clientY - box.top) / box.height * view[3]];
  };
  svg.addEventListener("wheel", event => {
    event.preventDefault();
    const [x, y] = at(event);
    const factor = event.deltaY < 0 ? 0.8 : 1.25;
    const width = Math.min(initial[2], view[2] * factor), height = Math.min(initial[3], view[3] * factor);
    view = [x - (x - view[0]) * width / view[2], y - (y - view[1]) * height / view[3], width, height];
    show();
  }, { passive: false });
  let from = null;
  svg.addEventListener("mousedown", event => { from = at(event); });
  svg.addEventListener("mousemove", event => {
    if (!from || !(event.buttons & 1)) return;
    const [x, y] = at(event);
    view[0] -= x - from[0];
    view[1] -= y - from[1];
    show();
  });
  svg.addEventListener("mouseup", () => { from = null; });
  svg.addEventListener("dblclick", () => { view = initial.slice(); show(); });
  svg.style.cursor = "zoom-in";
}

// Two runs of an axis side by side (before and after a compensation): the comparison's
// report, then each run's own.
function comparePage() {
  const params = new URLSearchParams(location.search);
  const before = params.get("before"), after = params.get("after");
  document.getElementById("title").textContent = "Run " + before + " and run " + after;
  document.getElementById("both").src = "/api/runs/" + encodeURIComponent(before) + "/report.html?after=" +
                                        encodeURIComponent(after);
  document.getElementById("before").src = "/api/runs/" + encodeURIComponent(before) + "/report.html";
  document.getElementById("after").src = "/api/runs/" + encodeURIComponent(after) + "/report.html";
}

// Start a plan: its JSON (from a file or typed), the instrument, the simulated machine's seed
// and pace; the server runs it and the job's page follows it.
function startPage() {
  const form = document.getElementById("start");
  form.elements.file.addEventListener("change", async () => {
    const file = form.elements.file.files[0];
    if (!file) return;
    form.elements.plan.value = await file.text();
    form.elements.plan_name.value = file.name;
  });
  form.addEventListener("submit", async event => {
    event.preventDefault();
    const message = document.getElementById("start-error");
    try {
      const body = { plan: JSON.parse(form.elements.plan.value), plan_name: form.elements.plan_name.value || "plan" };
      for (const key of ["device", "logger", "machine"]) if (form.elements[key].value) body[key] = form.elements[key].value;
      if (form.elements.seed.value) body.seed = Number(form.elements.seed.value);
      if (form.elements.time_scale.value) body.time_scale = Number(form.elements.time_scale.value);
      const job = await post("/api/jobs", body);
      location.href = "/job.html?id=" + job.id;
    } catch (error) {
      showError(message, error);
    }
  });
}

// The controls of a plan the server runs, on any page that has them (#prompt, #prompt-text,
// #answer, #stop, #job-error): the operator's request waiting for an answer and the stop
// button, asked every half second while it runs. `show(job)` draws the rest of the page.
function followJob(jobId, show) {
  const base = "/api/jobs/" + encodeURIComponent(jobId);
  const failed = error => showError(document.getElementById("job-error"), error);
  let answering = 0;
  document.getElementById("stop").addEventListener("click", () => post(base + "/stop", {}).catch(failed));
  document.getElementById("answer").addEventListener("click", () => post(base + "/answer", { prompt: answering })
    .catch(failed));
  const refresh = async () => {
    let job;
    try {
      job = await getJson(base);
    } catch (error) {
      failed(error);
      return;
    }
    document.getElementById("prompt").hidden = !job.prompt;
    if (job.prompt) {
      answering = job.prompt.number;
      document.getElementById("prompt-text").textContent = job.prompt.text;
    }
    document.getElementById("stop").disabled = job.status !== "running";
    document.getElementById("job-error").textContent = job.error || "";
    show(job);
    if (job.status === "running") setTimeout(refresh, 500);
  };
  refresh();
}

// A plan the server runs: its progress, the operator's request waiting for an answer, a stop
// button, the runs it records (each with its live page).
function jobPage() {
  const id = new URLSearchParams(location.search).get("id");
  document.getElementById("title").textContent = "Job " + id;
  followJob(id, job => {
    document.body.dataset.status = job.status;
    document.getElementById("plan").textContent = job.plan + " (" + job.type + "): " + job.status;
    const p = job.progress;
    const bar = document.getElementById("progress");
    bar.max = p.total || 1;
    bar.value = p.done;
    document.getElementById("progress-text").textContent = p.total
      ? p.done + " of " + p.total + (p.eta_s !== undefined ? ", about " + Math.round(p.eta_s) + " s left" : "") +
        (p.what ? ": " + p.what : "")
      : "";
    const runs = document.getElementById("runs");
    runs.replaceChildren();
    for (const run of job.runs) {
      const item = element("li");
      item.append(element("a", "run " + run, { href: "/run.html?id=" + run }), document.createTextNode(" · "),
                  element("a", "live", { href: "/live.html?id=" + run }));
      runs.append(item);
    }
    document.getElementById("messages").replaceChildren(...job.messages.map(m => element("li", m)));
  });
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
  // The reading stream: the newest readings the server sends (a few hundred a look, decimated),
  // the last 2000 of them drawn as a line against the device's time.
  const stream = [];
  const streamPlot = document.getElementById("stream");
  const drawStream = () => {
    const xs = stream.map(p => p[0]), ys = stream.map(p => p[1]);
    const x0 = Math.min(...xs), x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
    const px = x => 40 + (x1 > x0 ? (x - x0) / (x1 - x0) : 0.5) * 740;
    const py = y => 130 - (y1 > y0 ? (y - y0) / (y1 - y0) : 0.5) * 110;
    const line = document.createElementNS("http://www.w3.org/2000/svg", "polyline");
    line.setAttribute("points", stream.map(p => px(p[0]).toFixed(1) + "," + py(p[1]).toFixed(1)).join(" "));
    line.setAttribute("fill", "none");
    line.setAttribute("stroke", "#1e8449");
    const label = document.createElementNS("http://www.w3.org/2000/svg", "text");
    label.setAttribute("x", "45");
    label.setAttribute("y", "14");
    label.textContent = y1.toFixed(6) + " mm";
    const low = label.cloneNode();
    low.setAttribute("y", "145");
    low.textContent = y0.toFixed(6) + " mm";
    streamPlot.replaceChildren(line, label, low);
  };
  // A run this dashboard records: its job's controls (the operator's request, stop) here too.
  getJson("/api/jobs").then(list => {
    const job = list.jobs.find(j => j.status === "running" && j.runs.includes(Number(id)));
    if (!job) return;
    document.getElementById("controls").hidden = false;
    followJob(job.id, () => {});
  }).catch(() => {});  // a read-only dashboard runs no plans
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
    } else if (m.type === "stream") {
      for (let i = 0; i < m.value.length; ++i) stream.push([m.device_time_s[i], m.value[i]]);
      stream.splice(0, Math.max(0, stream.length - 2000));
      document.getElementById("reading").textContent =
        "reading " + m.value[m.value.length - 1].toFixed(6) + " mm, signal " + m.signal_pct + " %";
      drawStream();
    } else if (m.type === "environment") {
      const parts = [];
      const add = (name, v, digits, unitText) => { if (v !== null) parts.push(name + " " + v.toFixed(digits) + " " + unitText); };
      add("air", m.air_temp_c, 2, "°C");
      add("pressure", m.air_pressure_pa, 0, "Pa");
      add("humidity", m.humidity_pct, 1, "%");
      m.material_temp_c.forEach((v, k) => add("material " + (k + 1), v, 2, "°C"));
      document.getElementById("environment").textContent = parts.join(", ");
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
  if (document.body.dataset.page === "compare") comparePage();
  if (document.body.dataset.page === "start") startPage();
  if (document.body.dataset.page === "job") jobPage();
});
