"""The service, driven by a Python client generated from its own /openapi.json.

Run by scripts/openapi-client-test (which generates the client into a temporary folder and puts it
on the path) against a running server: TSPACE_URL is its base URL, TSPACE_FIXTURES the fixtures
folder. Nothing here is written by hand against the API: every call, parameter, model and enum
comes from the generated package, so a route, a body or a schema that the document gets wrong
fails here.
"""

import json
import os
import struct
from io import BytesIO
from pathlib import Path

from tspace_client import Client
from tspace_client.api.scenes import analyze, tangents, uv_layout
from tspace_client.api.service import problem_page
from tspace_client.models import (
    Method,
    OutputFormat,
    Problem,
    ProblemCode,
    Report,
    SceneUpload,
    UvLayoutFormat,
)
from tspace_client.types import File

FIXTURES = Path(os.environ["TSPACE_FIXTURES"])


def client() -> Client:
    return Client(base_url=os.environ["TSPACE_URL"], raise_on_unexpected_status=True, timeout=60)


def fixture(name: str, mime_type: str | None = None) -> File:
    path = FIXTURES / name
    return File(payload=BytesIO(path.read_bytes()), file_name=path.name, mime_type=mime_type)


def glb_json(glb: bytes) -> dict:
    """The JSON chunk of a GLB, after checking the container's header."""
    magic, version, length = struct.unpack_from("<4sII", glb, 0)
    assert (magic, version, length) == (b"glTF", 2, len(glb)), (magic, version, length)
    chunk_length, chunk_type = struct.unpack_from("<I4s", glb, 12)
    assert chunk_type == b"JSON"
    return json.loads(glb[20 : 20 + chunk_length])


def primitives(document: dict) -> list[dict]:
    return [p for mesh in document["meshes"] for p in mesh["primitives"]]


def test_a_glb_comes_back_with_tangents_and_its_summary():
    # Box has neither texture coordinates nor a normal map: the axis method and all=true give it
    # tangents all the same.
    glb = fixture("Box/Box.glb", "model/gltf-binary")
    response = tangents.sync_detailed(
        client=client(), body=SceneUpload(file=glb), method=Method.AXIS, all_=True
    )
    assert response.status_code == 200, response.content
    assert response.headers["content-type"] == "model/gltf-binary"
    assert isinstance(response.parsed, File)
    document = glb_json(response.parsed.payload.read())
    assert primitives(document), document
    for primitive in primitives(document):
        assert "TANGENT" in primitive["attributes"], primitive
    summary = json.loads(response.headers["x-tspace-report"])
    assert summary["generated"] == summary["primitives"] == len(primitives(document))
    assert response.headers["x-request-id"]


def avocado_upload() -> SceneUpload:
    upload = SceneUpload(file=fixture("Avocado/Avocado.gltf", "model/gltf+json"))
    upload["Avocado.bin"] = fixture("Avocado/Avocado.bin")
    return upload


def test_a_gltf_and_its_buffer_are_analyzed_into_a_typed_report():
    # Avocado comes with tangents of its own: analysis audits them against MikkTSpace.
    response = analyze.sync_detailed(client=client(), body=avocado_upload())
    assert response.status_code == 200, response.content
    report = response.parsed
    assert isinstance(report, Report), report
    assert report.input_format == "gltf"
    assert report.method == Method.MIKKTSPACE.value
    summary = report.summary
    assert (summary.primitives, summary.generated, summary.audited) == (1, 0, 1)
    assert summary.triangles == 682
    [primitive] = report.primitives
    assert primitive.action == "audited"
    assert primitive.audit.verdict in ("matches", "differs")
    assert summary.audits_disagreeing == (primitive.audit.verdict == "differs")
    findings = summary.findings
    assert findings.error + findings.warning + findings.info == len(report.findings)
    # Analysis writes nothing.
    assert not report.output_format


def test_the_uv_layout_comes_back_as_svg_or_png_and_its_options_are_typed():
    svg = uv_layout.sync_detailed(client=client(), body=avocado_upload())
    assert svg.status_code == 200, svg.content
    assert svg.headers["content-type"] == "image/svg+xml"
    assert isinstance(svg.parsed, File)
    text = svg.parsed.payload.read().decode()
    assert text.startswith("<svg ") and "Avocado.gltf" in text, text[:200]
    png = uv_layout.sync_detailed(
        client=client(), body=avocado_upload(), format_=UvLayoutFormat.PNG, mesh="0", primitive=0
    )
    assert png.status_code == 200, png.content
    assert png.headers["content-type"] == "image/png"
    assert png.parsed.payload.read().startswith(b"\x89PNG\r\n\x1a\n")


def test_a_gltf_and_its_buffer_come_back_as_one_gltf_with_new_tangents():
    response = tangents.sync_detailed(
        client=client(), body=avocado_upload(), overwrite=True, format_=OutputFormat.GLTF
    )
    assert response.status_code == 200, response.content
    assert response.headers["content-type"] == "model/gltf+json"
    summary = json.loads(response.headers["x-tspace-report"])
    assert (summary["primitives"], summary["generated"]) == (1, 1)
    document = json.loads(response.parsed.payload.read())
    [primitive] = primitives(document)
    tangent = document["accessors"][primitive["attributes"]["TANGENT"]]
    assert tangent["type"] == "VEC4"
    assert tangent["count"] == document["accessors"][primitive["attributes"]["POSITION"]]["count"]
    [buffer] = document["buffers"]
    assert buffer["uri"].startswith("data:application/octet-stream;base64,")


def test_a_refusal_is_a_typed_problem():
    # A .gltf whose buffer was not sent.
    response = analyze.sync_detailed(
        client=client(),
        body=SceneUpload(file=fixture("Avocado/Avocado.gltf", "model/gltf+json")),
    )
    assert response.status_code == 422
    problem = response.parsed
    assert isinstance(problem, Problem), problem
    assert problem.code == ProblemCode.MISSING_RESOURCE
    assert problem.type_ == "/problems/missing-resource"
    assert problem.status == 422
    assert "Avocado.bin" in problem.detail
    explained = problem_page.sync(client=client(), code=problem.code)
    assert explained.startswith("missing-resource (HTTP 422)"), explained
