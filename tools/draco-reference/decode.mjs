#!/usr/bin/env node
// Decodes every KHR_draco_mesh_compression primitive of one .glb or .gltf file with Google's
// reference Draco decoder (npm `draco3dgltf`, WASM; exact version pinned in package.json and
// package-lock.json) and prints ONE JSON object on stdout:
//
//   {"primitives": [
//     {"mesh": m, "primitive": p,
//      "indices": {"accessor": i, "values": [u32, ...]} | null,
//      "attributes": {"POSITION": {"accessor": a, "componentType": 5126, "values": [...]}, ...}},
//     {"mesh": m, "primitive": p, "error": "message"},          <- when that primitive failed
//     ...]}
//
// - Primitives come in mesh order, then primitive order; only those carrying the extension.
// - `indices` is the decoder's triangle list (GetTrianglesUInt32Array), or null when the Draco
//   geometry has no faces (a point cloud). `accessor` is the primitive's `indices` (null if absent).
// - Each attribute named in the extension's `attributes` is decoded INTO ITS ACCESSOR'S DECLARED
//   componentType (GetAttributeDataArrayForAllPoints with the matching DT_* type), so a float
//   accessor gets dequantized floats and an integer (KHR_mesh_quantization) accessor gets the
//   integers. `values` is flat: number of points x components. Float32 values are exact (a JS
//   number read from a Float32Array is the f32 value); a negative zero is written `-0.0` so that
//   it survives (JSON.stringify would write it as 0).
// - A primitive that cannot be decoded (bad buffer view, decoder error, attribute missing or of
//   another component count than its accessor's type) gets {"mesh", "primitive", "error"} only.
//
// Buffers: the GLB BIN chunk, data: URIs (base64), and relative files next to the input.
//
// `node decode.mjs --time ROUNDS FILE` times the decode alone instead (benches/compression.rs).
//
// Exit status: 0 when the file was read and parsed (whatever the primitives' errors); 1 when the
// file itself could not be read or parsed (message on stderr, nothing on stdout); 2 on bad usage.
//
// Test-only tooling: install with scripts/install-draco-reference.

import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const draco3d = require('draco3dgltf');

const GLB_MAGIC = 0x46546c67; // "glTF"
const CHUNK_JSON = 0x4e4f534a;
const CHUNK_BIN = 0x004e4942;
const COMPONENTS = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4, MAT2: 4, MAT3: 9, MAT4: 16 };
const NEG_ZERO = '\u0000tspace-negative-zero\u0000';

function usage() {
    process.stderr.write('usage: decode.mjs FILE.glb|FILE.gltf | decode.mjs --time ROUNDS FILE\n');
    process.exit(2);
}

function fail(message) {
    process.stderr.write(`decode.mjs: ${message}\n`);
    process.exit(1);
}

// The document's JSON and, for a GLB, its BIN chunk (null if none).
function readDocument(file) {
    const bytes = fs.readFileSync(file);
    if (bytes.length >= 4 && bytes.readUInt32LE(0) === GLB_MAGIC) {
        if (bytes.length < 12) throw new Error('GLB header truncated');
        const total = Math.min(bytes.readUInt32LE(8), bytes.length);
        let json = null;
        let bin = null;
        let off = 12;
        while (off + 8 <= total) {
            const len = bytes.readUInt32LE(off);
            const type = bytes.readUInt32LE(off + 4);
            if (off + 8 + len > total) throw new Error(`GLB chunk at ${off} overruns the file`);
            const chunk = bytes.subarray(off + 8, off + 8 + len);
            if (type === CHUNK_JSON && json === null) json = JSON.parse(chunk.toString('utf8'));
            else if (type === CHUNK_BIN && bin === null) bin = chunk;
            off += 8 + len;
        }
        if (json === null) throw new Error('GLB has no JSON chunk');
        return { json, bin };
    }
    return { json: JSON.parse(bytes.toString('utf8')), bin: null };
}

// Buffer i's bytes, loaded on first use; throws with a message on failure.
function bufferLoader(file, json, bin) {
    const cache = new Map();
    const dir = path.dirname(path.resolve(file));
    return (i) => {
        if (cache.has(i)) return cache.get(i);
        const b = (json.buffers || [])[i];
        if (b === undefined) throw new Error(`buffer ${i} does not exist`);
        let bytes;
        if (b.uri === undefined) {
            if (i !== 0 || bin === null) throw new Error(`buffer ${i} has no uri and there is no GLB BIN chunk`);
            bytes = bin;
        } else if (b.uri.startsWith('data:')) {
            const comma = b.uri.indexOf(',');
            if (comma < 0 || !b.uri.slice(0, comma).endsWith(';base64')) {
                throw new Error(`buffer ${i}: only base64 data: URIs are supported`);
            }
            bytes = Buffer.from(b.uri.slice(comma + 1), 'base64');
        } else {
            bytes = fs.readFileSync(path.join(dir, decodeURIComponent(b.uri)));
        }
        cache.set(i, bytes);
        return bytes;
    };
}

function viewBytes(json, buffer, v) {
    const bv = (json.bufferViews || [])[v];
    if (bv === undefined) throw new Error(`bufferView ${v} does not exist`);
    const b = buffer(bv.buffer);
    const start = bv.byteOffset || 0;
    if (start + bv.byteLength > b.length) {
        throw new Error(`bufferView ${v} (offset ${start}, length ${bv.byteLength}) overruns buffer ${bv.buffer} (${b.length} bytes)`);
    }
    return new Int8Array(b.buffer, b.byteOffset + start, bv.byteLength);
}

const M = await draco3d.createDecoderModule({});
const TYPES = {
    5120: [M.DT_INT8, Int8Array],
    5121: [M.DT_UINT8, Uint8Array],
    5122: [M.DT_INT16, Int16Array],
    5123: [M.DT_UINT16, Uint16Array],
    5125: [M.DT_UINT32, Uint32Array],
    5126: [M.DT_FLOAT32, Float32Array],
};

// Copies `n` elements of type Arr out of the WASM heap at ptr (the heap may have grown, so the
// current HEAPU8 is read after the decoder calls).
function fromHeap(Arr, ptr, n) {
    return new Arr(M.HEAPU8.buffer, ptr, n).slice();
}

function decodePrimitive(json, buffer, prim, ext) {
    const decoder = new M.Decoder();
    const dbuf = new M.DecoderBuffer();
    let geometry = null;
    try {
        const data = viewBytes(json, buffer, ext.bufferView);
        dbuf.Init(data, data.byteLength);
        const kind = decoder.GetEncodedGeometryType(dbuf);
        let status;
        if (kind === M.TRIANGULAR_MESH) {
            geometry = new M.Mesh();
            status = decoder.DecodeBufferToMesh(dbuf, geometry);
        } else if (kind === M.POINT_CLOUD) {
            geometry = new M.PointCloud();
            status = decoder.DecodeBufferToPointCloud(dbuf, geometry);
        } else {
            throw new Error('not a Draco geometry (unknown encoded geometry type)');
        }
        if (!status.ok() || geometry.ptr === 0) throw new Error(`Draco decode failed: ${status.error_msg()}`);
        const numPoints = geometry.num_points();

        let indices = null;
        if (kind === M.TRIANGULAR_MESH && geometry.num_faces() > 0) {
            const n = geometry.num_faces() * 3;
            const ptr = M._malloc(n * 4);
            try {
                if (!decoder.GetTrianglesUInt32Array(geometry, n * 4, ptr)) throw new Error('GetTrianglesUInt32Array failed');
                indices = { accessor: prim.indices ?? null, values: Array.from(fromHeap(Uint32Array, ptr, n)) };
            } finally {
                M._free(ptr);
            }
        }

        const attributes = {};
        for (const [semantic, uid] of Object.entries(ext.attributes || {})) {
            const a = (prim.attributes || {})[semantic];
            if (a === undefined) throw new Error(`attribute ${semantic}: in the extension but not in the primitive's attributes`);
            const acc = (json.accessors || [])[a];
            if (acc === undefined) throw new Error(`attribute ${semantic}: accessor ${a} does not exist`);
            const type = TYPES[acc.componentType];
            if (type === undefined) throw new Error(`attribute ${semantic}: accessor ${a} has unknown componentType ${acc.componentType}`);
            const [dt, Arr] = type;
            const attr = decoder.GetAttributeByUniqueId(geometry, uid);
            if (attr.ptr === 0) throw new Error(`attribute ${semantic}: no Draco attribute with unique id ${uid}`);
            const nc = attr.num_components();
            if (COMPONENTS[acc.type] !== nc) {
                throw new Error(`attribute ${semantic}: Draco attribute has ${nc} components, accessor ${a} is ${acc.type}`);
            }
            const n = numPoints * nc;
            const bytes = n * Arr.BYTES_PER_ELEMENT;
            const ptr = M._malloc(bytes);
            let values;
            try {
                if (!decoder.GetAttributeDataArrayForAllPoints(geometry, attr, dt, bytes, ptr)) {
                    throw new Error(`attribute ${semantic}: GetAttributeDataArrayForAllPoints failed (Draco data type ${attr.data_type()})`);
                }
                values = Array.from(fromHeap(Arr, ptr, n));
            } finally {
                M._free(ptr);
            }
            if (Arr === Float32Array) values = values.map((x) => (Object.is(x, -0) ? NEG_ZERO : x));
            attributes[semantic] = { accessor: a, componentType: acc.componentType, values };
        }
        return { indices, attributes };
    } finally {
        if (geometry !== null) M.destroy(geometry);
        M.destroy(dbuf);
        M.destroy(decoder);
    }
}

/// The decode alone, for timing: the stream decoded, the triangles and every attribute copied
/// out in the accessor's type (as tspace's decoder delivers them), nothing converted to JSON.
function decodeOnly(json, buffer, prim, ext) {
    const decoder = new M.Decoder();
    const dbuf = new M.DecoderBuffer();
    const geometry = new M.Mesh();
    try {
        const data = viewBytes(json, buffer, ext.bufferView);
        dbuf.Init(data, data.byteLength);
        const status = decoder.DecodeBufferToMesh(dbuf, geometry);
        if (!status.ok()) throw new Error(`Draco decode failed: ${status.error_msg()}`);
        const n = geometry.num_faces() * 3;
        let ptr = M._malloc(n * 4);
        decoder.GetTrianglesUInt32Array(geometry, n * 4, ptr);
        fromHeap(Uint32Array, ptr, n);
        M._free(ptr);
        for (const [semantic, uid] of Object.entries(ext.attributes || {})) {
            const [dt, Arr] = TYPES[json.accessors[prim.attributes[semantic]].componentType];
            const attr = decoder.GetAttributeByUniqueId(geometry, uid);
            const count = geometry.num_points() * attr.num_components();
            ptr = M._malloc(count * Arr.BYTES_PER_ELEMENT);
            decoder.GetAttributeDataArrayForAllPoints(geometry, attr, dt, count * Arr.BYTES_PER_ELEMENT, ptr);
            fromHeap(Arr, ptr, count);
            M._free(ptr);
        }
    } finally {
        M.destroy(geometry);
        M.destroy(dbuf);
        M.destroy(decoder);
    }
}

const args = process.argv.slice(2);
// `--time ROUNDS FILE`: decode every Draco primitive of FILE ROUNDS times (after one untimed
// round) and print {"rounds", "median_ms", "min_ms"} for one whole-file decode.
if (args[0] === '--time') {
    const rounds = Number(args[1]);
    if (args.length !== 3 || !(rounds >= 1)) usage();
    const doc = readDocument(args[2]);
    const buffer = bufferLoader(args[2], doc.json, doc.bin);
    const prims = [];
    for (const mesh of doc.json.meshes || []) {
        for (const prim of mesh.primitives || []) {
            const ext = prim.extensions && prim.extensions.KHR_draco_mesh_compression;
            if (ext) prims.push([prim, ext]);
        }
    }
    const once = () => prims.forEach(([prim, ext]) => decodeOnly(doc.json, buffer, prim, ext));
    once();
    const times = [];
    for (let r = 0; r < rounds; r++) {
        const start = process.hrtime.bigint();
        once();
        times.push(Number(process.hrtime.bigint() - start) / 1e6);
    }
    times.sort((a, b) => a - b);
    process.stdout.write(JSON.stringify({ rounds, median_ms: times[Math.floor(rounds / 2)], min_ms: times[0] }) + '\n');
    process.exit(0);
}
if (args.length !== 1 || args[0].startsWith('-')) usage();
const file = args[0];

let doc;
try {
    doc = readDocument(file);
} catch (err) {
    fail(`${file}: ${err instanceof Error ? err.message : String(err)}`);
}
const buffer = bufferLoader(file, doc.json, doc.bin);

const primitives = [];
(doc.json.meshes || []).forEach((mesh, m) => {
    (mesh.primitives || []).forEach((prim, p) => {
        const ext = prim.extensions && prim.extensions.KHR_draco_mesh_compression;
        if (!ext) return;
        try {
            primitives.push({ mesh: m, primitive: p, ...decodePrimitive(doc.json, buffer, prim, ext) });
        } catch (err) {
            primitives.push({ mesh: m, primitive: p, error: err instanceof Error ? err.message : String(err) });
        }
    });
});

const text = JSON.stringify({ primitives }).replaceAll(JSON.stringify(NEG_ZERO), '-0.0');
process.stdout.write(text + '\n');
