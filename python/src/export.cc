// atex.export_gltf: an asset to glTF 2.0 (KHR_gaussian_splatting and our extensions), as
// `atex export` does for .glb/.gltf (atex/converters/gltf.h).
#include <pybind11/pybind11.h>

#include "atex/converters/gltf.h"
#include "common.h"

namespace atex::python {
namespace {

py::dict ExportGltf(const AssetPtr& asset, const std::string& path, bool spz, bool meshopt, int meshopt_bits,
                    bool quantize, bool bake_textures, py::object time, bool textures, bool deformation, bool raw,
                    py::object up) {
  GltfExportOptions o;
  o.spz = spz;
  o.meshopt = meshopt;
  o.quantize = quantize;
  o.bake_textures = bake_textures;
  o.meshopt_float_bits = meshopt_bits;
  if (!time.is_none()) o.time = time.cast<double>();
  o.textures = textures;
  o.deformation = deformation;
  o.raw_parameters = raw;
  if (!up.is_none()) o.up = ValueOrThrow(ParseUpAxis(up.cast<std::string>()));
  Status status;
  {
    py::gil_scoped_release release;
    status = WriteGltfFile(path, asset->asset, o);
  }
  ThrowIfError(status);
  py::dict report;
  report["path"] = path;
  report["gaussians"] = asset->asset.gaussians.size();
  report["spz"] = spz;
  report["meshopt"] = meshopt;
  report["quantize"] = quantize;
  report["bake_textures"] = bake_textures;
  return report;
}

}  // namespace

void RegisterExport(py::module_& m) {
  m.def("export_gltf", &ExportGltf, py::arg("asset"), py::arg("path"), py::kw_only(), py::arg("spz") = false,
        py::arg("meshopt") = false, py::arg("meshopt_bits") = 0, py::arg("quantize") = false,
        py::arg("bake_textures") = false, py::arg("time") = py::none(),
        py::arg("textures") = true, py::arg("deformation") = true, py::arg("raw") = true, py::arg("up") = py::none(),
        "Writes `asset` as glTF 2.0 (.glb, or .gltf with a .bin beside it), as `atex export`:\n"
        "KHR_gaussian_splatting base attributes plus ATEX_gaussian_textures and ATEX_gaussian_deformation.\n"
        "spz: the base attributes as one SPZ stream (KHR_gaussian_splatting_compression_spz_2, lossy, ~22\n"
        "bytes per Gaussian, no raw parameters); meshopt: EXT_meshopt_compression (meshopt_bits: mantissa\n"
        "bits of lossy floats, 0 = exact); not both. quantize: KHR_mesh_quantization integer accessors\n"
        "(lossy, bounds in format_spec/extensions/README.md; with meshopt or alone, not with spz).\n"
        "bake_textures: each textured Gaussian baked into up to four plain ones, for players without\n"
        "ATEX_gaussian_textures. time: bake the deformation at this scene time.\n"
        "raw: the bit-exact raw parameters for import. up: '+y', '-y', '+z', ... (default: the asset's).\n"
        "Written through a temporary file. Returns a dict (path, gaussians, spz, meshopt, quantize,\n"
        "bake_textures).");
}

}  // namespace atex::python
