//! Builds small GLB files for tests: accessors from plain arrays, the rest of the document as
//! `serde_json` values.

use serde_json::{Value, json};

#[derive(Default)]
pub struct Builder {
    pub accessors: Vec<Value>,
    pub views: Vec<Value>,
    pub bin: Vec<u8>,
}

impl Builder {
    fn view(&mut self, bytes: &[u8], stride: Option<usize>) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut view =
            json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(stride) = stride {
            view["byteStride"] = json!(stride);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    /// A float accessor of `kind` (`VEC3`…), with min/max when asked (POSITION needs them).
    pub fn floats(&mut self, values: &[f32], kind: &str, min_max: bool) -> usize {
        let n = match kind {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT4" => 16,
            _ => panic!("kind {kind}"),
        };
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        let mut accessor = json!({"bufferView": view, "componentType": 5126,
            "count": values.len() / n, "type": kind});
        if min_max {
            let mut lo = vec![f32::INFINITY; n];
            let mut hi = vec![f32::NEG_INFINITY; n];
            for e in values.chunks(n) {
                for i in 0..n {
                    lo[i] = lo[i].min(e[i]);
                    hi[i] = hi[i].max(e[i]);
                }
            }
            accessor["min"] = json!(lo);
            accessor["max"] = json!(hi);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    pub fn indices(&mut self, values: &[u16]) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        self.accessors
            .push(json!({"bufferView": view, "componentType": 5123,
            "count": values.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }

    pub fn indices_u32(&mut self, values: &[u32]) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        self.accessors
            .push(json!({"bufferView": view, "componentType": 5125,
            "count": values.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }

    /// An image stored in the buffer (its bytes are not checked: tspace passes images
    /// through); its index in `images`, which the caller puts in the document.
    pub fn image(&mut self, bytes: &[u8], mime_type: &str) -> Value {
        let view = self.view(bytes, None);
        json!({"bufferView": view, "mimeType": mime_type})
    }

    /// Normalized unsigned bytes, VEC3 (3-byte elements, so the view has a 4-byte stride).
    pub fn colors_u8(&mut self, values: &[[u8; 3]]) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|c| [c[0], c[1], c[2], 0]).collect();
        let view = self.view(&bytes, Some(4));
        self.accessors
            .push(json!({"bufferView": view, "componentType": 5121,
            "normalized": true, "count": values.len(), "type": "VEC3"}));
        self.accessors.len() - 1
    }

    /// The document with the accessors, views and buffer filled in.
    pub fn document(&self, mut doc: Value) -> Value {
        doc["asset"] = json!({"version": "2.0"});
        doc["accessors"] = json!(self.accessors);
        doc["bufferViews"] = json!(self.views);
        doc["buffers"] = json!([{"byteLength": self.bin.len()}]);
        doc
    }

    pub fn glb(&self, doc: Value) -> Vec<u8> {
        let text = serde_json::to_string(&self.document(doc)).unwrap();
        tspace::scene::gltf::glb::write(text.as_bytes(), Some(&self.bin), &[]).unwrap()
    }
}

/// A material list whose material 0 has a normal map on `tex_coord`.
pub fn normal_mapped(tex_coord: u32) -> Value {
    json!([{"normalTexture": {"index": 0, "texCoord": tex_coord}}])
}

/// Enough texture and image to make `normal_mapped` valid.
pub fn texture_stub(doc: &mut Value) {
    // A 1x1 PNG as a data URI keeps the document self-contained for the validator.
    doc["images"] = json!([{"uri": "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8BQDwAEhQGAhKmMIQAAAABJRU5ErkJggg=="}]);
    doc["textures"] = json!([{"source": 0}]);
}

/// A normal-mapped, gently waved unit grid of `2 n²` triangles with u32 indices, as a GLB: the
/// stand-in for a real scene in service tests and benches.
pub fn grid(n: usize) -> Vec<u8> {
    let (b, mut doc) = grid_document(n);
    texture_stub(&mut doc);
    b.glb(doc)
}

/// [`grid`]'s buffer and document, before its texture is added.
fn grid_document(n: usize) -> (Builder, Value) {
    let mut positions = Vec::with_capacity((n + 1) * (n + 1) * 3);
    let mut normals = Vec::with_capacity(positions.capacity());
    let mut uvs = Vec::with_capacity((n + 1) * (n + 1) * 2);
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            positions.extend([u, v, (u * 7.0).sin() * 0.1]);
            normals.extend([0.0, 0.0, 1.0]);
            uvs.extend([u, v]);
        }
    }
    let mut indices: Vec<u32> = Vec::with_capacity(n * n * 6);
    let row = (n + 1) as u32;
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let v = j * row + i;
            indices.extend([v, v + 1, v + row + 1, v, v + row + 1, v + row]);
        }
    }
    let mut b = Builder::default();
    let position = b.floats(&positions, "VEC3", true);
    let normal = b.floats(&normals, "VEC3", false);
    let uv = b.floats(&uvs, "VEC2", false);
    let index = b.indices_u32(&indices);
    let doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal,
            "TEXCOORD_0": uv}, "indices": index, "material": 0}]}],
        "materials": normal_mapped(0),
    });
    (b, doc)
}

/// [`grid`] whose normal map is a stored image of `image_bytes` (noise, not a decodable PNG):
/// the shape of most real scenes, whose files are mostly textures, such as DamagedHelmet.
pub fn grid_with_image(n: usize, image_bytes: usize) -> Vec<u8> {
    let (mut b, mut doc) = grid_document(n);
    // A fixed xorshift stream: incompressible, and the same every run.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let noise: Vec<u8> = (0..image_bytes)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u8
        })
        .collect();
    doc["images"] = json!([b.image(&noise, "image/png")]);
    doc["textures"] = json!([{"source": 0}]);
    b.glb(doc)
}

/// `shape` as a normal-mapped GLB with u32 indices.
pub fn shape_glb(shape: &crate::shapes::Shape) -> Vec<u8> {
    let flat3: Vec<f32> = shape.positions.iter().flatten().copied().collect();
    let normals: Vec<f32> = shape.normals.iter().flatten().copied().collect();
    let uvs: Vec<f32> = shape.uvs.iter().flatten().copied().collect();
    let mut b = Builder::default();
    let position = b.floats(&flat3, "VEC3", true);
    let normal = b.floats(&normals, "VEC3", false);
    let uv = b.floats(&uvs, "VEC2", false);
    let index = b.indices_u32(&shape.indices);
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"name": shape.name, "primitives": [{"attributes": {"POSITION": position,
            "NORMAL": normal, "TEXCOORD_0": uv}, "indices": index, "material": 0}]}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    b.glb(doc)
}

/// A normal-mapped unit quad whose interleaved vertices and indices are compressed by
/// meshoptimizer and whose file requires EXT_meshopt_compression, as a GLB.
pub fn meshopt_quad() -> Vec<u8> {
    let positions = [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let uvs = [[0f32, 0.], [1., 0.], [1., 1.], [0., 1.]];
    let vertices: Vec<[f32; 8]> = (0..4)
        .map(|v| {
            let [x, y, z] = positions[v];
            let [s, t] = uvs[v];
            [x, y, z, 0., 0., 1., s, t]
        })
        .collect();
    let indices = [0u32, 1, 2, 0, 2, 3];
    let vertex_data = meshopt::encode_vertex_buffer(&vertices).unwrap();
    let index_data = meshopt::encode_index_buffer(&indices, 4).unwrap();
    let mut bin = vertex_data.clone();
    bin.resize(bin.len().div_ceil(4) * 4, 0);
    let index_offset = bin.len();
    bin.extend_from_slice(&index_data);
    bin.resize(bin.len().div_ceil(4) * 4, 0);
    let doc = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["EXT_meshopt_compression"],
        "extensionsRequired": ["EXT_meshopt_compression"],
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "buffers": [{"byteLength": bin.len()},
            {"byteLength": 140, "extensions": {"EXT_meshopt_compression": {"fallback": true}}}],
        "bufferViews": [
            {"buffer": 1, "byteOffset": 0, "byteLength": 128, "byteStride": 32, "target": 34962,
             "extensions": {"EXT_meshopt_compression": {"buffer": 0, "byteOffset": 0,
                "byteLength": vertex_data.len(), "byteStride": 32, "count": 4, "mode": "ATTRIBUTES"}}},
            {"buffer": 1, "byteOffset": 128, "byteLength": 12, "target": 34963,
             "extensions": {"EXT_meshopt_compression": {"buffer": 0, "byteOffset": index_offset,
                "byteLength": index_data.len(), "byteStride": 2, "count": 6, "mode": "TRIANGLES"}}}
        ],
        "accessors": [
            {"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 0, "byteOffset": 12, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 0, "byteOffset": 24, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": 3, "material": 0}]}],
        "materials": [{"normalTexture": {"index": 0}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "normal.png"}],
    });
    tspace::scene::gltf::glb::write(&serde_json::to_vec(&doc).unwrap(), Some(&bin), &[]).unwrap()
}
