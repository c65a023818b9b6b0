// The 3D view: the scene tspace wrote, shaded with its tangents and a test normal map, and the
// tangent frames drawn as lines coloured by handedness. three.js is built into the binary
// (vendor/three.min.js, see scripts/vendor-three).

import * as THREE from "/page/vendor/three.min.js";

const PLUS = new THREE.Color(0x0072b2);
const MINUS = new THREE.Color(0xd55e00);
const NORMAL = new THREE.Color(0x009e73);
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
  return { renderer, camera, controls, render, frameToggle };
}

// A 1×1 grey image for every texture the scene names but did not carry (images not supplied):
// the view replaces the materials anyway, and nothing is fetched from elsewhere.
function placeholderImage() {
  const png = Uint8Array.from(atob("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAAAAAA6fptVAAAACklEQVR4nGNgAAAAAgABSK+kcQAAAABJRU5ErkJggg=="), (c) => c.charCodeAt(0));
  return URL.createObjectURL(new Blob([png], { type: "image/png" }));
}

export async function showScene(canvas, glb) {
  if (!state) state = { ...setup(canvas), placeholder: placeholderImage() };
  const manager = new THREE.LoadingManager();
  manager.setURLModifier((url) => (url.startsWith("blob:") ? url : state.placeholder));
  const loader = new THREE.GLTFLoader(manager);
  const gltf = await loader.parseAsync(glb, "");
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
  state.scene = scene;
  state.frames = all;
  const { camera, controls } = state;
  camera.near = size / 1000;
  camera.far = size * 100;
  camera.position.copy(centre).add(new THREE.Vector3(0.6, 0.4, 1).normalize().multiplyScalar(size * 1.2));
  camera.updateProjectionMatrix();
  controls.target.copy(centre);
  controls.update();
  state.render();
  canvas.dataset.frames = String(all.children.reduce((n, l) => n + l.geometry.getAttribute("position").count / 6, 0));
  canvas.dataset.view = "ready";
}
