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
