// The page at `/`: pick or drop a scene's files, choose options, and see what tspace found,
// the UV layout, and downloads. Plain ES module, no framework; it calls the same /v1 routes a
// script would, so what it shows is what they answer. Everything a file supplies (names, mesh
// names, messages) is shown as text, never as markup.

const SCENE = /\.(glb|gltf|obj)$/i;
const SUMMARY = [
  ["primitives", "primitives"],
  ["generated", "given tangents"],
  ["audited", "kept and audited"],
  ["skipped", "skipped"],
  ["triangles", "triangles"],
  ["vertices_added", "vertices added by splits"],
  ["mirrored_uv_triangles", "mirrored UV triangles"],
  ["zero_uv_area_triangles", "zero-UV-area triangles"],
  ["degenerate_triangles", "degenerate triangles"],
  ["fallback_tangents", "repaired tangents (corners)"],
  ["handedness_flip_vertices", "handedness flips (vertices)"],
  ["audits_disagreeing", "kept tangents that disagree with MikkTSpace"],
];

const $ = (id) => document.getElementById(id);
let chosen = [];
let urls = [];

function show(files) {
  chosen = Array.from(files);
  const list = $("chosen");
  list.replaceChildren(
    ...chosen.map((f) => {
      const item = document.createElement("li");
      item.textContent = `${f.name} (${f.size.toLocaleString("en")} bytes)`;
      return item;
    }),
  );
}

function query(extra) {
  const q = new URLSearchParams({ method: $("method").value, normals: $("normals").value });
  if ($("overwrite").checked) q.set("overwrite", "true");
  if ($("all").checked) q.set("all", "true");
  for (const [k, v] of Object.entries(extra || {})) q.set(k, v);
  return q.toString();
}

function upload() {
  const main = chosen.find((f) => SCENE.test(f.name));
  if (!main) throw { title: "No scene chosen", detail: "Choose a .glb, .gltf or .obj file (and the files it refers to)." };
  const form = new FormData();
  form.append("file", main, main.name);
  for (const f of chosen) if (f !== main) form.append(f.name, f, f.name);
  return { form, main };
}

async function call(path, params, accept) {
  const { form } = upload();
  const headers = accept ? { Accept: accept } : {};
  const key = $("api-key").value.trim();
  if (key) headers.Authorization = `Bearer ${key}`;
  const response = await fetch(`${path}?${query(params)}`, { method: "POST", body: form, headers });
  if (!response.ok) {
    const type = response.headers.get("content-type") || "";
    if (type.startsWith("application/problem+json")) {
      const problem = await response.json();
      throw { title: problem.title, detail: problem.detail, status: response.status, code: problem.code };
    }
    throw { title: `${response.status} ${response.statusText}`, detail: await response.text() };
  }
  return response;
}

// The report and the scene of a multipart/mixed answer (see src/server/mixed.rs): each part's
// headers end at a blank line, and its body at CRLF and the next delimiter.
async function reportAndScene(response) {
  const boundary = /boundary=([^;\s]+)/.exec(response.headers.get("content-type") || "");
  if (!boundary) throw { title: "Unexpected answer", detail: "the service sent no multipart boundary" };
  const bytes = new Uint8Array(await response.arrayBuffer());
  const encode = (text) => new TextEncoder().encode(text);
  const find = (needle, from) => {
    outer: for (let i = from; i + needle.length <= bytes.length; i++) {
      for (let k = 0; k < needle.length; k++) if (bytes[i + k] !== needle[k]) continue outer;
      return i;
    }
    return -1;
  };
  const delimiter = encode(`\r\n--${boundary[1]}`);
  const blank = encode("\r\n\r\n");
  const part = (from) => {
    const start = find(blank, from) + blank.length;
    const end = find(delimiter, start);
    if (start < blank.length || end < 0) throw { title: "Unexpected answer", detail: "a part of the multipart answer is cut short" };
    return [start, end];
  };
  const [reportStart, reportEnd] = part(0);
  const [sceneStart, sceneEnd] = part(reportEnd + delimiter.length);
  return {
    report: JSON.parse(new TextDecoder().decode(bytes.subarray(reportStart, reportEnd))),
    scene: new Blob([bytes.subarray(sceneStart, sceneEnd)], { type: "model/gltf-binary" }),
  };
}

// The 3D view's key to the highlighted classes, with the debug report's counts.
function renderHighlightKey(debugColors) {
  const names = {
    mirrored_uv: "mirrored UVs",
    repaired_tangent: "repaired tangents",
    zero_uv_area: "zero UV area",
    degenerate: "degenerate",
  };
  const keys = (debugColors ? debugColors.classes : [])
    .filter((c) => c.class !== "ordinary" && c.triangles > 0)
    .map((c) => {
      const key = document.createElement("span");
      key.className = "key";
      key.style.background = c.color;
      key.dataset.class = c.class;
      key.dataset.triangles = String(c.triangles);
      key.textContent = `${names[c.class] || c.class}: ${c.triangles.toLocaleString("en")}`;
      return key;
    });
  if (keys.length === 0) keys.push(document.createTextNode("none"));
  $("highlight-key").replaceChildren(...keys);
}

// What to do on this page about a problem whose detail speaks of requests and parts.
function hint(problem) {
  if (problem.code !== "missing-resource") return "";
  const named = /refers to "([^"]+)"/.exec(problem.detail || "");
  const file = named ? `“${named[1]}”` : "the files it names";
  return `Choose ${file} together with the scene: select all of the scene's files at once, or drop them together.`;
}

function fail(problem) {
  $("error-title").textContent = problem.title || "Something went wrong";
  $("error-detail").textContent = problem.detail || String(problem);
  const advice = hint(problem);
  $("error-hint").textContent = advice;
  $("error-hint").hidden = !advice;
  $("error").hidden = false;
  $("status").textContent = "";
}

function row(cells, tag = "td") {
  const tr = document.createElement("tr");
  for (const c of cells) {
    const cell = document.createElement(tag);
    cell.textContent = c;
    tr.append(cell);
  }
  return tr;
}

function render(report) {
  const s = report.summary;
  $("summary").replaceChildren(
    ...SUMMARY.flatMap(([key, label]) => {
      const dt = document.createElement("dt");
      dt.textContent = label;
      const dd = document.createElement("dd");
      dd.id = `summary-${key}`;
      dd.textContent = (s[key] ?? 0).toLocaleString("en");
      return [dt, dd];
    }),
  );
  const findings = report.findings.map((f) => {
    const item = document.createElement("li");
    const severity = document.createElement("span");
    severity.className = `severity severity-${f.severity}`;
    severity.textContent = f.severity;
    const where = f.primitive ? ` (meshes[${f.primitive[0]}].primitives[${f.primitive[1]}])` : "";
    const count = f.count !== undefined ? `${f.count.toLocaleString("en")} ` : "";
    item.append(severity, ` ${count}${f.message}${where}`);
    item.dataset.code = f.code;
    return item;
  });
  if (findings.length === 0) {
    const none = document.createElement("li");
    none.textContent = "nothing to report";
    findings.push(none);
  }
  $("findings").replaceChildren(...findings);

  const table = document.createElement("table");
  table.append(row(["primitive", "mesh", "action", "triangles", "mirrored", "zero UV area", "degenerate", "repaired", "flips", "audit"], "th"));
  for (const p of report.primitives) {
    const d = p.diagnostics || {};
    const n = (name) => (d[name] ? d[name].count : "");
    const degenerate = d.triangles === undefined ? "" :
      n("duplicate_position_triangles") + n("zero_area_triangles") + n("non_finite_triangles");
    table.append(row([
      `meshes[${p.mesh}].primitives[${p.primitive}]`,
      p.mesh_name || "",
      p.action + (p.reason ? ` (${p.reason})` : "") + (p.shared_with ? ` (as meshes[${p.shared_with[0]}].primitives[${p.shared_with[1]}])` : ""),
      d.triangles ?? "",
      n("mirrored_uv_triangles"),
      n("zero_uv_area_triangles"),
      degenerate,
      d.fallback_tangents ? d.fallback_tangents.count : "",
      n("handedness_flip_vertices"),
      p.audit ? p.audit.verdict : "",
    ].map(String)));
  }
  $("primitives").replaceChildren(table);
}

function link(anchor, blob, name) {
  const url = URL.createObjectURL(blob);
  urls.push(url);
  anchor.href = url;
  if (name) anchor.download = name;
}

async function run(event) {
  event.preventDefault();
  $("error").hidden = true;
  $("results").hidden = true;
  for (const url of urls) URL.revokeObjectURL(url);
  urls = [];
  try {
    const { main } = upload();
    $("status").textContent = `Reading ${main.name}…`;
    const report = await (await call("/v1/analyze")).json();
    render(report);
    link($("download-report"), new Blob([JSON.stringify(report, null, 2)], { type: "application/json" }), "report.json");
    $("status").textContent = "Drawing the UV layout…";
    const picture = $("uv-layout");
    try {
      const svg = await (await call("/v1/uv-layout")).blob();
      const url = URL.createObjectURL(svg);
      urls.push(url);
      picture.src = url;
      picture.hidden = false;
    } catch (problem) {
      // A scene with nothing to draw still has its report and its scene.
      picture.hidden = true;
      picture.removeAttribute("src");
      picture.alt = problem.detail || "no layout";
    }
    $("status").textContent = "Writing the scene…";
    // The scene to ship and the same scene painted by class, for the highlights, side by side.
    const [scene, debug] = await Promise.all([
      call("/v1/tangents").then((r) => r.blob()),
      call("/v1/tangents", { debug: "colors" }, "multipart/mixed").then(reportAndScene),
    ]);
    const stem = main.name.replace(/\.[^.]*$/, "");
    link($("download-scene"), scene, `${stem}.tspace.glb`);
    link($("download-debug"), debug.scene, `${stem}.debug.glb`);
    renderHighlightKey(debug.report.debug_colors);
    $("results").hidden = false;
    $("status").textContent = "Drawing the scene in 3D…";
    try {
      // Loaded when first needed, so that a browser without WebGL still gets the rest.
      const { showScene } = await import("/page/view.js");
      await showScene($("view"), await scene.arrayBuffer(), await debug.scene.arrayBuffer());
      $("status").textContent = `Done: ${main.name}`;
    } catch (error) {
      $("status").textContent = `Done: ${main.name} (no 3D view: ${error.message || error})`;
    }
  } catch (problem) {
    fail(problem);
  }
}

function init() {
  $("files").addEventListener("change", (e) => show(e.target.files));
  const drop = $("drop");
  for (const name of ["dragenter", "dragover"]) {
    drop.addEventListener(name, (e) => {
      e.preventDefault();
      drop.classList.add("over");
    });
  }
  for (const name of ["dragleave", "drop"]) {
    drop.addEventListener(name, () => drop.classList.remove("over"));
  }
  drop.addEventListener("drop", (e) => {
    e.preventDefault();
    show(e.dataTransfer.files);
  });
  $("scene-form").addEventListener("submit", run);
  document.body.dataset.ready = "true";
}

init();
