"""atex.export_gltf: the sample as glTF, plain and with the base attributes as one SPZ stream."""

import json
import struct

import pytest

import atex


def glb_json(path):
    """The JSON chunk of a .glb (test-side parsing, independent of the library)."""
    data = open(path, "rb").read()
    magic, version, length = struct.unpack_from("<III", data, 0)
    assert magic == 0x46546C67 and version == 2 and length == len(data)
    chunk_length, chunk_type = struct.unpack_from("<II", data, 12)
    assert chunk_type == 0x4E4F534A
    return json.loads(data[20:20 + chunk_length])


def test_export_plain_and_spz(sample, tmp_path):
    plain, spz = tmp_path / "plain.glb", tmp_path / "spz.glb"
    report = atex.export_gltf(sample, str(plain))
    assert report["gaussians"] == sample.gaussian_count and not report["spz"]
    report = atex.export_gltf(sample, str(spz), spz=True)
    assert report["spz"]
    doc = glb_json(spz)
    assert "KHR_gaussian_splatting_compression_spz_2" in doc["extensionsRequired"]
    primitive = doc["meshes"][0]["primitives"][0]
    stream = primitive["extensions"]["KHR_gaussian_splatting"]["extensions"]["KHR_gaussian_splatting_compression_spz_2"]
    assert "bufferView" in stream
    base = {name: i for name, i in primitive["attributes"].items()
            if name == "POSITION" or name.startswith("KHR_gaussian_splatting:")}
    assert "POSITION" in base and len(base) >= 4
    assert all("bufferView" not in doc["accessors"][i] for i in base.values())  # the SPZ stream holds their data
    assert doc["accessors"][primitive["attributes"]["POSITION"]]["count"] == sample.gaussian_count
    assert spz.stat().st_size * 2 < plain.stat().st_size
    assert "KHR_gaussian_splatting_compression_spz_2" not in glb_json(plain).get("extensionsUsed", [])


def test_export_refuses_bad_options(sample, tmp_path):
    with pytest.raises(atex.Error, match="meshopt"):
        atex.export_gltf(sample, str(tmp_path / "x.glb"), spz=True, meshopt=True)
    with pytest.raises(atex.Error):
        atex.export_gltf(sample, str(tmp_path / "y.glb"), up="sideways")
    assert not (tmp_path / "x.glb").exists() and not (tmp_path / "y.glb").exists()


def test_export_quantized_and_baked(sample, tmp_path):
    plain, quantized = tmp_path / "plain.glb", tmp_path / "quantized.glb"
    atex.export_gltf(sample, str(plain))
    report = atex.export_gltf(sample, str(quantized), quantize=True)
    assert report["quantize"] and not report["bake_textures"]
    doc = glb_json(quantized)
    assert "KHR_mesh_quantization" in doc["extensionsRequired"]
    position = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    assert position["componentType"] in (5120, 5122)  # BYTE or SHORT, not FLOAT
    assert position["count"] == sample.gaussian_count
    assert quantized.stat().st_size < plain.stat().st_size
    with pytest.raises(atex.Error):
        atex.export_gltf(sample, str(tmp_path / "qz.glb"), quantize=True, spz=True)

    baked = tmp_path / "baked.glb"
    report = atex.export_gltf(sample, str(baked), time=0.5, bake_textures=True)
    assert report["bake_textures"]
    doc = glb_json(baked)
    assert "ATEX_gaussian_textures" not in doc.get("extensionsUsed", [])
    assert "ATEX_gaussian_textures" in glb_json(plain).get("extensionsUsed", [])
    count = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]["count"]
    assert count >= sample.gaussian_count  # a textured Gaussian becomes one to four plain ones
