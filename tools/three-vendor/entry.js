// What the page's 3D view uses from three.js, bundled into one minified ES module by
// scripts/vendor-three (three's npm package ships no minified build, and its addons import the
// bare specifier "three", which a page under a strict CSP cannot map without an inline script).
export * from "three";
export { OrbitControls } from "three/addons/controls/OrbitControls.js";
export { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
