"""A Python client generated from the served OpenAPI document must fetch meshes.

openapi-python-client generates a client from the document the running server serves at
/openapi.json, and the test downloads binary glTF of the demo city with it: a z16 tile
(operationId `tile_glb`), and `/scene` (operationId `scene`: GLB by default, the statistics as
JSON with `format=json` or `Accept: application/json`) when the document has it.

openapi-python-client knows binary bodies only as application/octet-stream; the config next to
this file maps model/gltf-binary to it. A 200 documented as `type: string, format: binary` then
becomes a `File`; anything else (a byte array schema, an unknown content type, which the generator
drops with a warning) fails here, because a client that cannot return the bytes is no client.

Run by scripts/check-openapi, which starts the server in demo mode and sets CITYMESH_URL.
"""

import enum
import importlib
import inspect
import json
import os
import pkgutil
import re
import struct
import subprocess
import sys
import urllib.request
import warnings
from pathlib import Path

import httpx
import pytest

HERE = Path(__file__).resolve().parent
CONFIG = HERE / "openapi-python-client.yaml"
PACKAGE = "citymesh_generated_client"
# The demo city is a 1 km x 1 km procedural city centred on Karlsruhe palace (8.4044 E, 49.0135 N).
TILE = (16, 34297, 22502)  # the z16 tile holding the palace point
BBOX = "8.400,49.010,8.409,49.017"  # inside the demo city
# The operations the test calls; warnings of the generator about them fail the test.
USED = {"tile_glb", "scene", "scene_glb", "scene_stats"}


def base_url() -> str:
    url = os.environ.get("CITYMESH_URL")
    if not url:
        pytest.fail("CITYMESH_URL is not set: run scripts/check-openapi, which starts the server")
    return url.rstrip("/")


@pytest.fixture(scope="module")
def document() -> dict:
    with urllib.request.urlopen(base_url() + "/openapi.json", timeout=30) as r:
        return json.load(r)


def operations(document: dict) -> dict:
    """operationId -> (method, path, operation object)."""
    found = {}
    for path, item in document.get("paths", {}).items():
        for method, op in item.items():
            if isinstance(op, dict) and "operationId" in op:
                found[op["operationId"]] = (method.upper(), path, op)
    return found


class Generated:
    """The generated package: its modules by operationId, its File type, a client."""

    def __init__(self, package, log: str):
        self.package = package
        self.log = log
        self.modules = {}
        api = importlib.import_module(package.__name__ + ".api")
        for info in pkgutil.walk_packages(api.__path__, api.__name__ + "."):
            if not info.ispkg:
                module = importlib.import_module(info.name)
                self.modules[info.name.rsplit(".", 1)[1]] = module
        self.File = importlib.import_module(package.__name__ + ".types").File

    def module(self, operation_id: str):
        if operation_id not in self.modules:
            pytest.fail(
                f"the generated client has no function for operationId {operation_id!r} "
                f"(it has {sorted(self.modules)}); generator output:\n{self.log}"
            )
        return self.modules[operation_id]

    def client(self, **kwargs):
        return self.package.Client(
            base_url=base_url(),
            raise_on_unexpected_status=True,
            timeout=httpx.Timeout(60.0),
            **kwargs,
        )


@pytest.fixture(scope="module")
def generated(tmp_path_factory, document) -> Generated:
    out = tmp_path_factory.mktemp("generated")
    command = [
        str(Path(sys.executable).parent / "openapi-python-client"),
        "generate",
        "--url",
        base_url() + "/openapi.json",
        "--output-path",
        str(out / PACKAGE),
        "--meta",
        "none",
        "--config",
        str(CONFIG),
    ]
    proc = subprocess.run(command, check=False, capture_output=True, text=True, timeout=300)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"openapi-python-client failed:\n{log}"
    # "WARNING parsing GET /scene.glb within meshes." then the reason: the generator left that
    # operation (or one of its responses) out.
    ids = {(m, p): op_id for op_id, (m, p, _) in operations(document).items()}
    warned = {ids.get((m, p), f"{m} {p}") for m, p in re.findall(r"WARNING parsing (\w+) (\S+) within", log)}
    if warned & USED:
        pytest.fail(f"openapi-python-client dropped parts of {sorted(warned & USED)}:\n{log}")
    if warned:
        warnings.warn(f"openapi-python-client warned about {sorted(warned)}:\n{log}")
    sys.path.insert(0, str(out))
    return Generated(importlib.import_module(PACKAGE), log)


def fetch_glb(operation, what: str, **kwargs):
    """Calls a generated operation that should answer GLB, explaining a client that parses JSON."""
    try:
        return operation.sync_detailed(**kwargs)
    except ValueError as e:  # json.JSONDecodeError and UnicodeDecodeError are ValueErrors
        pytest.fail(
            f"{what}: the generated client parsed the GLB answer as JSON ({e!r}). openapi-python-client "
            "takes the first content type it knows of a response: list model/gltf-binary before "
            "application/json in the operation's 200 response"
        )


def glb_bytes(generated: Generated, response, what: str) -> bytes:
    """The GLB the client returned, checked: a File, whole, a glTF 2.0 binary with a JSON chunk."""
    assert response.status_code == 200, f"{what}: HTTP {response.status_code}: {response.content[:300]!r}"
    parsed = response.parsed
    assert isinstance(parsed, generated.File), (
        f"{what}: the generated client returned {type(parsed).__name__} for the 200 response, not "
        "the bytes as a File: document the GLB body as model/gltf-binary with schema "
        "{type: string, format: binary}"
    )
    data = parsed.payload.read()
    assert data == response.content, f"{what}: the File holds other bytes than the response"
    assert data[:4] == b"glTF", f"{what}: not binary glTF, starts with {data[:16]!r}"
    version, total = struct.unpack_from("<II", data, 4)
    assert version == 2, f"{what}: glTF version {version}"
    assert total == len(data), f"{what}: the header declares {total} bytes, got {len(data)}"
    chunk_length, chunk_type = struct.unpack_from("<I4s", data, 12)
    assert chunk_type == b"JSON", f"{what}: the first chunk is {chunk_type!r}, not JSON"
    gltf = json.loads(data[20 : 20 + chunk_length])
    assert gltf["asset"]["version"] == "2.0", f"{what}: asset {gltf.get('asset')}"
    assert gltf.get("meshes"), f"{what}: no meshes"
    return data


def resolve(document: dict, schema: dict) -> dict:
    """Follows local `$ref`s (#/components/...)."""
    while "$ref" in schema and schema["$ref"].startswith("#/"):
        target = document
        for part in schema["$ref"][2:].split("/"):
            target = target[part.replace("~1", "/").replace("~0", "~")]
        schema = target
    return schema


def test_binary_bodies_are_documented_as_binary(document):
    """schemathesis does not look inside binary bodies, so their schemas are checked here: every
    GLB (model/gltf-binary) or application/octet-stream body of any operation must be
    `type: string, format: binary`, the form generated clients turn into bytes."""
    ops = operations(document)
    assert "tile_glb" in ops, f"no operation with operationId tile_glb (have {sorted(ops)})"
    content = ops["tile_glb"][2]["responses"]["200"].get("content", {})
    assert "model/gltf-binary" in content, f"tile_glb: 200 has no model/gltf-binary ({list(content)})"
    wrong = []
    for method, path, op in ops.values():
        bodies = [(f"{status} response", r.get("content", {})) for status, r in op.get("responses", {}).items()]
        bodies.append(("request body", op.get("requestBody", {}).get("content", {})))
        for where, content in bodies:
            for media in ("model/gltf-binary", "application/octet-stream"):
                if media in content:
                    schema = resolve(document, content[media].get("schema", {}))
                    if (schema.get("type"), schema.get("format")) != ("string", "binary"):
                        wrong.append(f"{method} {path} {where} {media}: {schema}")
    assert not wrong, "binary bodies not documented as {type: string, format: binary}:\n" + "\n".join(wrong)


def test_tile_glb_downloads_a_tile_of_the_demo_city(generated):
    z, x, y = TILE
    with generated.client() as client:
        what = f"GET /tiles/{z}/{x}/{y}.glb"
        response = fetch_glb(generated.module("tile_glb"), what, z=z, x=x, y=y, client=client)
    data = glb_bytes(generated, response, what)
    print(f"tile {z}/{x}/{y}: {len(data)} bytes")


def scene_format_value(module, value: str):
    """The generated `format` argument: an enum member when the document gives an enum."""
    for obj in vars(module).values():
        if isinstance(obj, type) and issubclass(obj, enum.Enum):
            for member in obj:
                if member.value == value:
                    return member
    return value


def test_scene_via_the_client(generated, document):
    if "scene" not in operations(document):
        pytest.skip("the document has no operation with operationId scene")
    scene = generated.module("scene")
    params = inspect.signature(scene.sync_detailed).parameters
    assert "bbox" in params, f"scene has no bbox argument: {list(params)}"
    with generated.client() as client:
        what = f"GET /scene?bbox={BBOX}"
        data = glb_bytes(generated, fetch_glb(scene, what, client=client, bbox=BBOX), what)
        if "scene_glb" in generated.modules:
            what = f"GET /scene.glb?bbox={BBOX}"
            same = fetch_glb(generated.module("scene_glb"), what, client=client, bbox=BBOX)
            assert glb_bytes(generated, same, what) == data, (
                "/scene and /scene.glb gave different bytes for the same bbox"
            )
        stats = generated.module("scene_stats").sync_detailed(client=client, bbox=BBOX)
        assert stats.status_code == 200, f"/scene/stats: HTTP {stats.status_code}"
        expected = json.loads(stats.content)
        assert expected["glb_bytes"] == len(data), (
            f"/scene/stats says glb_bytes {expected['glb_bytes']}, the GLB has {len(data)}"
        )
        assert expected["buildings"]["generated"] > 0, f"no buildings in {BBOX}: {expected['buildings']}"

        as_json = []
        format_arg = next((name for name in params if name.rstrip("_") == "format"), None)
        if format_arg:
            with_format = scene.sync_detailed(
                client=client, bbox=BBOX, **{format_arg: scene_format_value(scene, "json")}
            )
            as_json.append(("format=json", with_format))
        else:
            pytest.fail(f"scene has no format argument: {list(params)}")
    with generated.client(headers={"Accept": "application/json"}) as client:
        as_json.append(("Accept: application/json", scene.sync_detailed(client=client, bbox=BBOX)))

    for how, r in as_json:
        assert r.status_code == 200, f"/scene with {how}: HTTP {r.status_code}: {r.content[:300]!r}"
        content_type = r.headers.get("content-type", "")
        assert content_type.startswith("application/json"), f"/scene with {how}: Content-Type {content_type}"
        figures = json.loads(r.content)
        # The generation time differs between runs; every other figure is the same.
        for d in (figures, expected):
            d.pop("generation_ms", None)
        assert figures == expected, f"/scene with {how} differs from /scene/stats"
    print(f"scene {BBOX}: {len(data)} bytes; figures as JSON by format=json and by Accept")
