// The 3D view: the scene tspace wrote, shaded with its tangents and a test normal map, and the
// tangent frames drawn as lines coloured by handedness. three.js is built into the binary
// (vendor/three.min.js, see scripts/vendor-three).

import * as THREE from "/page/vendor/three.min.js";

const PLUS = new THREE.Color(0x0072b2);
const MINUS = new THREE.Color(0xd55e00);
const NORMAL = new THREE.Color(0x009e73);
// The debug scene's classes (debug=colors), as COLOR_0 holds them: linear, which is what
// THREE.Color makes of an sRGB hex. Ordinary triangles are not highlighted.
const ORDINARY = new THREE.Color(0xc9c9c9);
const CLASSES = [
  ["mirrored_uv", new THREE.Color(0x56b4e9)],
  ["repaired_tangent", new THREE.Color(0xcc79a7)],
  ["zero_uv_area", new THREE.Color(0xe69f00)],
  ["degenerate", new THREE.Color(0xd55e00)],
];
// Classes whose triangles are usually few and small (or have no area at all): each also gets
// a marker that keeps its size on screen, so that it can be found.
const MARKED = new Set(["repaired_tangent", "zero_uv_area", "degenerate"]);
// Enough frames to read a seam, few enough to draw at once on a software renderer.
const MAX_FRAMES = 20000;

let state = null;

// A normal map of raised ridges running along u, eight to a texture: where the tangents are
// right they shade as one pattern across a seam, where handedness or direction is wrong the
// ridges break or light from the wrong side.
function testNormalMap() {
  const size = 128;
  const data = new Uint8Array(size * size * 4);
  for (let y = 0; y < size; y++) {
    for (let x = 0; x < size; x++) {
      const u = x / size, v = y / size;
      const slope = Math.cos(2 * Math.PI * 8 * v) * 0.9;
      const bump = Math.cos(2 * Math.PI * 8 * u) * 0.25;
      const n = new THREE.Vector3(-bump, -slope, 1).normalize();
      const i = 4 * (y * size + x);
      data[i] = (n.x * 0.5 + 0.5) * 255;
      data[i + 1] = (n.y * 0.5 + 0.5) * 255;
      data[i + 2] = (n.z * 0.5 + 0.5) * 255;
      data[i + 3] = 255;
    }
  }
  const texture = new THREE.DataTexture(data, size, size, THREE.RGBAFormat);
  texture.wrapS = texture.wrapT = THREE.RepeatWrapping;
  texture.needsUpdate = true;
  return texture;
}

// Lines from each vertex (a sample of them on large meshes) along its tangent, bitangent
// (normal × tangent × w) and normal.
function frames(mesh, length) {
  const geometry = mesh.geometry;
  const position = geometry.getAttribute("position");
  const normal = geometry.getAttribute("normal");
  const tangent = geometry.getAttribute("tangent");
  if (!position || !normal || !tangent) return null;
  const step = Math.max(1, Math.ceil(position.count / MAX_FRAMES));
  const points = [];
  const colours = [];
  const p = new THREE.Vector3(), n = new THREE.Vector3(), t = new THREE.Vector3(), b = new THREE.Vector3();
  const line = (from, direction, colour) => {
    points.push(from.x, from.y, from.z);
    points.push(from.x + direction.x * length, from.y + direction.y * length, from.z + direction.z * length);
    colours.push(colour.r, colour.g, colour.b, colour.r, colour.g, colour.b);
  };
  for (let i = 0; i < position.count; i += step) {
    p.fromBufferAttribute(position, i);
    n.fromBufferAttribute(normal, i).normalize();
    t.set(tangent.getX(i), tangent.getY(i), tangent.getZ(i));
    const w = tangent.getW(i) < 0 ? -1 : 1;
    b.crossVectors(n, t).multiplyScalar(w);
    const hand = w > 0 ? PLUS : MINUS;
    line(p, t, hand);
    line(p, b, hand.clone().lerp(new THREE.Color(1, 1, 1), 0.5));
    line(p, n, NORMAL);
  }
  const lines = new THREE.BufferGeometry();
  lines.setAttribute("position", new THREE.Float32BufferAttribute(points, 3));
  lines.setAttribute("color", new THREE.Float32BufferAttribute(colours, 3));
  const segments = new THREE.LineSegments(lines, new THREE.LineBasicMaterial({ vertexColors: true }));
  segments.matrixAutoUpdate = false;
  segments.matrix.copy(mesh.matrixWorld);
  return segments;
}

// The class of a COLOR_0 value, or null for ordinary (or any colour that is not a class's).
function classOf(r, g, b) {
  const near = (c) => Math.abs(c.r - r) < 2e-3 && Math.abs(c.g - g) < 2e-3 && Math.abs(c.b - b) < 2e-3;
  if (near(ORDINARY)) return null;
  for (const [name, colour] of CLASSES) if (near(colour)) return name;
  return null;
}

// From the debug-coloured scene (the same scene, painted by class): every mesh reduced to its
// problem triangles, drawn over the shaded view in their class colours, markers for the small
// ones, and the triangles of each class counted once per geometry, as the report counts them.
function highlights(debugScene) {
  const counts = Object.fromEntries(CLASSES.map(([name]) => [name, 0]));
  const counted = new Set();
  const overlays = [];
  const markerPoints = [];
  const markerColours = [];
  const material = new THREE.MeshBasicMaterial({
    vertexColors: true, side: THREE.DoubleSide, transparent: true, opacity: 0.75, depthWrite: false,
    polygonOffset: true, polygonOffsetFactor: -2, polygonOffsetUnits: -2,
  });
  const corner = new THREE.Vector3(), centre = new THREE.Vector3();
  debugScene.updateMatrixWorld(true);
  debugScene.traverse((object) => {
    if (!object.isMesh) return;
    const geometry = object.geometry;
    const colour = geometry.getAttribute("color");
    const position = geometry.getAttribute("position");
    if (!colour || !position) return;
    const index = geometry.getIndex();
    const corners = index ? index.count : position.count;
    const vertex = (c) => (index ? index.getX(c) : c);
    const first = !counted.has(geometry.uuid);
    counted.add(geometry.uuid);
    const kept = [];
    for (let c = 0; c + 2 < corners; c += 3) {
      const v = vertex(c);
      const name = classOf(colour.getX(v), colour.getY(v), colour.getZ(v));
      if (!name) continue;
      if (first) counts[name]++;
      kept.push(vertex(c), vertex(c + 1), vertex(c + 2));
      if (MARKED.has(name)) {
        centre.set(0, 0, 0);
        for (let k = 0; k < 3; k++) centre.add(corner.fromBufferAttribute(position, vertex(c + k)));
        centre.divideScalar(3).applyMatrix4(object.matrixWorld);
        markerPoints.push(centre.x, centre.y, centre.z);
        markerColours.push(colour.getX(v), colour.getY(v), colour.getZ(v));
      }
    }
    if (kept.length === 0) return;
    const problems = new THREE.BufferGeometry();
    problems.setAttribute("position", position);
    problems.setAttribute("color", colour);
    problems.setIndex(kept);
    const overlay = new THREE.Mesh(problems, material);
    overlay.matrixAutoUpdate = false;
    overlay.matrix.copy(object.matrixWorld);
    overlays.push(overlay);
  });
  const group = new THREE.Group();
  for (const overlay of overlays) group.add(overlay);
  if (markerPoints.length) {
    const markers = new THREE.BufferGeometry();
    markers.setAttribute("position", new THREE.Float32BufferAttribute(markerPoints, 3));
    markers.setAttribute("color", new THREE.Float32BufferAttribute(markerColours, 3));
    const points = new THREE.Points(markers, new THREE.PointsMaterial({
      size: 7, sizeAttenuation: false, vertexColors: true, depthTest: false,
    }));
    points.renderOrder = 2;
    group.add(points);
  }
  return { group, counts, markers: markerPoints.length / 3 };
}

function setup(canvas) {
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
  const camera = new THREE.PerspectiveCamera(40, 1, 0.001, 1000);
  const controls = new THREE.OrbitControls(camera, canvas);
  const render = () => {
    const { clientWidth: w, clientHeight: h } = canvas;
    if (w && h && (canvas.width !== Math.floor(w * renderer.getPixelRatio()) || canvas.height !== Math.floor(h * renderer.getPixelRatio()))) {
      renderer.setSize(w, h, false);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
    }
    if (state && state.scene) renderer.render(state.scene, camera);
  };
  controls.addEventListener("change", render);
  new ResizeObserver(render).observe(canvas);
  const frameToggle = document.getElementById("frames");
  frameToggle.addEventListener("change", () => {
    if (state && state.frames) state.frames.visible = frameToggle.checked;
    render();
  });
  const highlightToggle = document.getElementById("highlight");
  highlightToggle.addEventListener("change", () => {
    if (state && state.highlights) state.highlights.visible = highlightToggle.checked;
    render();
  });
  return { renderer, camera, controls, render, frameToggle, highlightToggle };
}

// A 1×1 grey image for every texture the scene names but did not carry (images not supplied):
// the view replaces the materials anyway, and nothing is fetched from elsewhere.
function placeholderImage() {
  const png = Uint8Array.from(atob("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAAAAAA6fptVAAAACklEQVR4nGNgAAAAAgABSK+kcQAAAABJRU5ErkJggg=="), (c) => c.charCodeAt(0));
  return URL.createObjectURL(new Blob([png], { type: "image/png" }));
}

// `glb` is the scene tspace wrote, `debugGlb` the same scene written with debug=colors (or
// null): its problem triangles are drawn over the first.
export async function showScene(canvas, glb, debugGlb) {
  if (!state) state = { ...setup(canvas), placeholder: placeholderImage() };
  const manager = new THREE.LoadingManager();
  manager.setURLModifier((url) => (url.startsWith("blob:") ? url : state.placeholder));
  const loader = new THREE.GLTFLoader(manager);
  const gltf = await loader.parseAsync(glb, "");
  const debug = debugGlb ? await loader.parseAsync(debugGlb, "") : null;
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xf4f4f4);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 2.2);
  sun.position.set(2, 3, 4);
  scene.add(sun);
  scene.add(gltf.scene);
  gltf.scene.updateMatrixWorld(true);
  const box = new THREE.Box3().setFromObject(gltf.scene);
  const size = box.getSize(new THREE.Vector3()).length() || 1;
  const centre = box.getCenter(new THREE.Vector3());
  const map = testNormalMap();
  map.repeat.set(6, 6);
  const all = new THREE.Group();
  gltf.scene.traverse((object) => {
    if (!object.isMesh) return;
    object.material = new THREE.MeshStandardMaterial({
      color: 0xc8c8c8, roughness: 0.45, metalness: 0, normalMap: map, side: THREE.DoubleSide,
    });
    const lines = frames(object, size * 0.012);
    if (lines) all.add(lines);
  });
  all.visible = state.frameToggle.checked;
  scene.add(all);
  const marked = debug ? highlights(debug.scene) : { group: new THREE.Group(), counts: {}, markers: 0 };
  marked.group.visible = state.highlightToggle.checked;
  scene.add(marked.group);
  state.scene = scene;
  state.frames = all;
  state.highlights = marked.group;
  const { camera, controls } = state;
  camera.near = size / 1000;
  camera.far = size * 100;
  camera.position.copy(centre).add(new THREE.Vector3(0.6, 0.4, 1).normalize().multiplyScalar(size * 1.2));
  camera.updateProjectionMatrix();
  controls.target.copy(centre);
  controls.update();
  state.render();
  canvas.dataset.frames = String(all.children.reduce((n, l) => n + l.geometry.getAttribute("position").count / 6, 0));
  canvas.dataset.highlighted = JSON.stringify(marked.counts);
  canvas.dataset.markers = String(marked.markers);
  canvas.dataset.view = "ready";
}
