// Decodes every EXT_meshopt_compression / KHR_meshopt_compression buffer view of a GLB with
// meshoptimizer's own decoder (npm `meshoptimizer`, its MeshoptDecoder: the WASM decoder three.js's
// GLTFLoader uses) and prints one JSON object: {"decoder": version, "views": {index: base64 of the
// decoded bytes}}. Test-only (tests/meshopt_output.rs compares it with tspace's own decoder).
//
// Usage: node decode.mjs FILE.glb
import { readFileSync } from 'node:fs';
import { MeshoptDecoder } from 'meshoptimizer/decoder';

const bytes = readFileSync(process.argv[2]);
const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
if (view.getUint32(0, true) !== 0x46546c67) throw new Error('not a GLB');
let json = null;
let bin = null;
for (let at = 12; at + 8 <= bytes.length; ) {
    const length = view.getUint32(at, true);
    const kind = view.getUint32(at + 4, true);
    const chunk = bytes.subarray(at + 8, at + 8 + length);
    if (kind === 0x4e4f534a) json = JSON.parse(new TextDecoder().decode(chunk));
    else if (kind === 0x004e4942 && bin === null) bin = chunk;
    at += 8 + length;
}
await MeshoptDecoder.ready;
const out = {};
(json.bufferViews || []).forEach((v, i) => {
    const ext = (v.extensions || {}).EXT_meshopt_compression || (v.extensions || {}).KHR_meshopt_compression;
    if (!ext) return;
    if (ext.buffer !== 0 || json.buffers[0].uri !== undefined) throw new Error(`bufferViews[${i}]: data not in the BIN chunk`);
    const source = bin.subarray(ext.byteOffset || 0, (ext.byteOffset || 0) + ext.byteLength);
    const target = new Uint8Array(ext.count * ext.byteStride);
    MeshoptDecoder.decodeGltfBuffer(target, ext.count, ext.byteStride, source, ext.mode, ext.filter || 'NONE');
    out[i] = Buffer.from(target).toString('base64');
});
const version = JSON.parse(readFileSync(new URL('./node_modules/meshoptimizer/package.json', import.meta.url))).version;
console.log(JSON.stringify({ decoder: `meshoptimizer ${version}`, supported: MeshoptDecoder.supported, views: out }));
