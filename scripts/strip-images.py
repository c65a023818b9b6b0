#!/usr/bin/env python3
"""Usage: strip-images.py IN.gltf OUT.gltf

Writes OUT.gltf: IN.gltf without its images, textures and samplers, and without every texture
reference in its materials (any `...Texture` member holding a textureInfo, at any depth, so
extension textures go too); extensions no longer used by anything that is left (such as
KHR_texture_transform, which lives in textureInfo) are dropped from extensionsUsed and
extensionsRequired. Meshes, accessors and buffers are untouched, and external buffers are copied
beside OUT when OUT is in another folder.

Why: the fixtures keep only mesh data, so the PNG/JPEG files they reference are absent, and
gltf-transform refuses to read a document whose images are missing (gltfpack replaces them with
broken data: URIs). Used by scripts/make-compressed-fixtures; a copy of the helper of the Draco
evaluation (strip_images.py), made stricter.
"""

import json
import os
import shutil
import sys

# Extensions that can only appear on textures or textureInfo objects.
TEXTURE_ONLY_EXTENSIONS = {
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "MSFT_texture_dds",
}


def strip_textures(node):
    """Removes every `<name>Texture` member that is a textureInfo (an object with `index`)."""
    if isinstance(node, dict):
        for key in list(node):
            value = node[key]
            if key.endswith("Texture") and isinstance(value, dict) and "index" in value:
                del node[key]
            else:
                strip_textures(value)
    elif isinstance(node, list):
        for value in node:
            strip_textures(value)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    src, dst = sys.argv[1], sys.argv[2]
    with open(src, encoding="utf-8") as f:
        doc = json.load(f)
    for key in ("images", "textures", "samplers"):
        doc.pop(key, None)
    for material in doc.get("materials", []):
        strip_textures(material)
    text = json.dumps(doc)
    for key in ("extensionsUsed", "extensionsRequired"):
        if key in doc:
            kept = [e for e in doc[key] if e not in TEXTURE_ONLY_EXTENSIONS or f'"{e}":' in text]
            if kept:
                doc[key] = kept
            else:
                del doc[key]
    src_dir = os.path.dirname(os.path.abspath(src))
    dst_dir = os.path.dirname(os.path.abspath(dst))
    for buffer in doc.get("buffers", []):
        uri = buffer.get("uri")
        if uri is not None and not uri.startswith("data:") and src_dir != dst_dir:
            shutil.copyfile(os.path.join(src_dir, uri), os.path.join(dst_dir, uri))
    with open(dst, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
