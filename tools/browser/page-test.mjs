// The page at `/`, in a real browser: Debian's chromium, driven by playwright-core, with
// software WebGL. Run by tests/browser.rs against a running server:
//   node tools/browser/page-test.mjs BASE_URL FIXTURES_DIR SCREENSHOT_DIR [CORPUS_DIR]
// With CORPUS_DIR (../shared/corpus, where present), the corpus's DamagedHelmet, SciFiHelmet and
// spot go through the page too.
// Exits 0 when every check passes, 1 (with the reason) when one fails.

import { chromium } from "playwright-core";
import { execFileSync } from "node:child_process";
import { readFileSync, mkdirSync } from "node:fs";
import { basename, join } from "node:path";

const [base, fixtures, shots, corpus] = process.argv.slice(2);
mkdirSync(shots, { recursive: true });

function executable() {
  for (const name of ["chromium", "chromium-browser"]) {
    try {
      return execFileSync("sh", ["-c", `command -v ${name}`]).toString().trim();
    } catch {}
  }
  throw new Error("chromium not found");
}

function check(condition, message) {
  if (!condition) throw new Error(message);
}

// The highlighted triangles the 3D view counted from the debug scene's COLOR_0, against the
// debug report's counts the page's key shows: they must be the same, class by class.
async function checkHighlights(page, name) {
  const counted = JSON.parse(await page.getAttribute("#view", "data-highlighted"));
  const keys = await page.$$eval("#highlight-key .key", (spans) =>
    spans.map((k) => [k.dataset.class, Number(k.dataset.triangles)]));
  const reported = Object.fromEntries(keys);
  for (const [cls, n] of Object.entries(counted)) {
    check((reported[cls] || 0) === n, `${name}: the view highlights ${n} ${cls} triangles, the report counts ${reported[cls] || 0}`);
  }
  for (const [cls, n] of keys) {
    check(counted[cls] === n, `${name}: the report counts ${n} ${cls} triangles, the view highlights ${counted[cls]}`);
  }
  return counted;
}

// A sample of the 3D view's pixels, to tell two renderings apart.
async function viewPixels(page) {
  return page.evaluate(() => {
    const view = document.getElementById("view");
    const copy = document.createElement("canvas");
    copy.width = view.width;
    copy.height = view.height;
    const context = copy.getContext("2d");
    context.drawImage(view, 0, 0);
    const pixels = context.getImageData(0, 0, copy.width, copy.height).data;
    const sample = [];
    for (let i = 0; i < pixels.length; i += 4 * 97) sample.push(`${pixels[i]},${pixels[i + 1]},${pixels[i + 2]}`);
    return sample;
  });
}

const mirror = join(fixtures, "NormalTangentMirrorTest");
const gltf = join(mirror, "NormalTangentMirrorTest.gltf");
const bin = join(mirror, "NormalTangentMirrorTest.bin");

// What /v1/analyze says about the same files: the page must show the same counts.
async function expectedSummary(files = [gltf, bin]) {
  const form = new FormData();
  files.forEach((path, i) => {
    const name = basename(path);
    form.append(i === 0 ? "file" : name, new Blob([readFileSync(path)]), name);
  });
  const response = await fetch(`${base}/v1/analyze?method=mikktspace&normals=auto`, { method: "POST", body: form });
  check(response.ok, `/v1/analyze answered ${response.status}`);
  return (await response.json()).summary;
}

const browser = await chromium.launch({
  executablePath: executable(),
  headless: true,
  chromiumSandbox: false,
  args: ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
});
const problems = [];
try {
  const page = await browser.newPage({ acceptDownloads: true, viewport: { width: 1200, height: 900 } });
  page.on("console", (m) => { if (m.type() === "error") problems.push(`console: ${m.text()}`); });
  page.on("pageerror", (e) => problems.push(`page error: ${e.message}`));

  await page.goto(`${base}/`);
  await page.waitForSelector("body[data-ready=true]", { timeout: 15000 });

  // NormalTangentMirrorTest's .gltf and .bin: the counts, the picture, a download.
  await page.setInputFiles("#files", [gltf, bin]);
  await page.click("#run");
  await page.waitForSelector("#results:not([hidden])", { timeout: 60000 });
  const expected = await expectedSummary();
  for (const key of ["triangles", "mirrored_uv_triangles", "audited"]) {
    const shown = (await page.textContent(`#summary-${key}`)).replace(/,/g, "");
    check(shown === String(expected[key]), `summary ${key}: page shows ${shown}, /v1/analyze ${expected[key]}`);
  }
  const findings = await page.locator("#findings li").count();
  check(findings === expected.findings.error + expected.findings.warning + expected.findings.info,
    `${findings} findings shown`);
  const picture = await page.waitForFunction(() => {
    const img = document.getElementById("uv-layout");
    return img.complete && img.naturalWidth > 0 ? img.naturalWidth : 0;
  }, null, { timeout: 30000 });
  check((await picture.jsonValue()) > 0, "the UV layout did not load");
  // The 3D view: drawn, not blank (more than a handful of colours), with tangent frames.
  await page.waitForSelector("#view[data-view=ready]", { timeout: 60000 });
  const highlighted = await viewPixels(page);
  const colours = new Set(highlighted).size;
  check(colours > 50, `the 3D view looks blank (${colours} colours)`);
  // Problem triangles: the mirrored ones /v1/analyze counts are highlighted, and the highlights
  // show (the view changes when they are turned off).
  const counted = await checkHighlights(page, "mirror");
  check(counted.mirrored_uv === expected.mirrored_uv_triangles,
    `the view highlights ${counted.mirrored_uv} mirrored triangles, /v1/analyze counts ${expected.mirrored_uv_triangles}`);
  await page.locator("#view").screenshot({ path: join(shots, "view-mirror-highlights.png") });
  await page.uncheck("#highlight");
  const plain = await viewPixels(page);
  const changed = plain.filter((p, i) => p !== highlighted[i]).length;
  check(changed > 0, "turning the highlights off changes nothing in the view");
  await page.check("#highlight");
  const frameCount = Number(await page.getAttribute("#view", "data-frames"));
  check(frameCount > 0, "no tangent frames drawn");
  await page.locator("#view").screenshot({ path: join(shots, "view-mirror.png") });
  const [download] = await Promise.all([page.waitForEvent("download"), page.click("#download-scene")]);
  const saved = join(shots, download.suggestedFilename());
  await download.saveAs(saved);
  const glb = readFileSync(saved);
  check(glb.toString("latin1", 0, 4) === "glTF", "the download is not a GLB");
  const jsonLength = glb.readUInt32LE(12);
  const document = JSON.parse(glb.toString("utf8", 20, 20 + jsonLength));
  check(document.meshes[0].primitives[0].attributes.TANGENT !== undefined, "the downloaded scene has no TANGENT");
  // The debug-coloured scene: COLOR_0, the unlit material, and a name that says what it is.
  const [debugDownload] = await Promise.all([page.waitForEvent("download"), page.click("#download-debug")]);
  check(debugDownload.suggestedFilename().endsWith(".debug.glb"), `debug download named ${debugDownload.suggestedFilename()}`);
  const debugSaved = join(shots, debugDownload.suggestedFilename());
  await debugDownload.saveAs(debugSaved);
  const debugGlb = readFileSync(debugSaved);
  const debugDocument = JSON.parse(debugGlb.toString("utf8", 20, 20 + debugGlb.readUInt32LE(12)));
  const painted = debugDocument.meshes[0].primitives[0];
  check(painted.attributes.COLOR_0 !== undefined, "the debug scene has no COLOR_0");
  check(debugDocument.materials[painted.material].extensions.KHR_materials_unlit !== undefined,
    "the debug scene's material is not unlit");
  await page.screenshot({ path: join(shots, "page-mirror.png"), fullPage: true });

  // The corpus's assets, where it is present: the counts, and a 3D view that is not blank.
  const assets = corpus ? [
    ["helmet", ["gltf_DamagedHelmet/glTF-Binary/DamagedHelmet.glb"]],
    ["scifi", ["gltf_SciFiHelmet_no_images/SciFiHelmet.gltf", "gltf_SciFiHelmet_no_images/SciFiHelmet.bin"]],
    ["spot", ["obj_spot/spot_triangulated.obj"]],
  ] : [];
  for (const [name, relative] of assets) {
    const files = relative.map((r) => join(corpus, r));
    await page.goto(`${base}/`);
    await page.waitForSelector("body[data-ready=true]");
    await page.setInputFiles("#files", files);
    await page.click("#run");
    await page.waitForSelector("#view[data-view=ready]", { timeout: 120000 });
    const wanted = await expectedSummary(files);
    const shown = (await page.textContent("#summary-triangles")).replace(/,/g, "");
    check(shown === String(wanted.triangles), `${name}: page shows ${shown} triangles, /v1/analyze ${wanted.triangles}`);
    const marked = await checkHighlights(page, name);
    check(marked.mirrored_uv > 0 === wanted.mirrored_uv_triangles > 0, `${name}: mirrored triangles highlighted: ${marked.mirrored_uv}`);
    await page.locator("#view").screenshot({ path: join(shots, `view-${name}.png`) });
    await page.screenshot({ path: join(shots, `page-${name}.png`), fullPage: true });
  }

  // The .gltf alone: its buffer is missing, and the page says so with the problem's title.
  await page.goto(`${base}/`);
  await page.waitForSelector("body[data-ready=true]");
  await page.setInputFiles("#files", [gltf]);
  await page.click("#run");
  await page.waitForSelector("#error:not([hidden])", { timeout: 30000 });
  const title = await page.textContent("#error-title");
  check(title === "A file the scene refers to was not supplied", `error title: ${title}`);
  const advice = await page.textContent("#error-hint");
  check(advice.includes("“NormalTangentMirrorTest.bin”"), `error hint: ${advice}`);
  await page.screenshot({ path: join(shots, "page-missing-buffer.png"), fullPage: true });
  // The failed request is the browser's own console error ("Failed to load resource: 422");
  // anything else is the page's.
  const own = problems.filter((p) => !/Failed to load resource: the server responded with a status of 422/.test(p));
  check(own.length === 0, own.join("; "));
  console.log(`browser: page test passed (screenshots in ${shots})`);
} catch (error) {
  console.log(`browser: page test failed: ${error.message}`);
  process.exitCode = 1;
} finally {
  await browser.close();
}
