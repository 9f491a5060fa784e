// atex.read / atex.decode, atex.Asset (numpy views of the C++ arrays), Asset.write,
// Asset.deform and atex.Gaussians.
#include <pybind11/stl.h>

#include <string>
#include <utility>

#include "atex/converters/convert.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "atex/fit.h"
#include "common.h"
#include "dlpack.h"

namespace atex::python {

namespace {

using GaussiansPtr = std::shared_ptr<const Gaussians>;
struct GaussiansView {
  GaussiansPtr g;
};
struct TexturesView {
  AssetPtr owner;
  const TexturePool& pool() const { return *owner->asset.textures; }
};
struct DeformationView {
  AssetPtr owner;
  const DeformationField& field() const { return *owner->asset.deformation; }
};

py::ssize_t Rows(size_t values, size_t per_row) { return static_cast<py::ssize_t>(per_row ? values / per_row : 0); }

// Tensors of every Gaussian array (DLPack producers over the same memory as the views).
py::dict GaussianTensors(const GaussiansPtr& g) {
  const auto n = static_cast<int64_t>(g->size());
  const auto tensor = [&](const std::vector<float>& v, std::vector<int64_t> shape) {
    TensorData t;
    t.owner = g;
    t.data = const_cast<float*>(v.data());  // consumers get read access by contract (the asset never changes)
    t.shape = std::move(shape);
    t.read_only = true;
    return MakeTensor(std::move(t));
  };
  py::dict out;
  out["positions"] = tensor(g->positions, {n, 3});
  out["rotations"] = tensor(g->rotations, {n, 4});
  out["log_scales"] = tensor(g->log_scales, {n, 3});
  out["opacity_logits"] = tensor(g->opacity_logits, {n});
  out["sh"] = tensor(g->sh, {n, g->sh_coeffs(), 3});
  if (g->has_time_windows()) out["time_windows"] = tensor(g->time_windows, {n, 2});
  return out;
}

void RegisterGaussians(py::module_& m) {
  py::class_<GaussiansView>(m, "Gaussians",
                            "Gaussian parameters (canonical, or deformed to one time by Asset.deform), as read-only\n"
                            "numpy views of the C++ arrays (atex/model.h, BasicGaussians):\n"
                            "  positions [N, 3] world units; rotations [N, 4] quaternion (w, x, y, z), normalised on\n"
                            "  use; log_scales [N, 3] natural log of the standard deviations; opacity_logits [N]\n"
                            "  (opacity = sigmoid); sh [N, K, 3], K = (sh_degree + 1)^2, coefficient-major, RGB\n"
                            "  innermost, k = 0 is DC.")
      .def_property_readonly("count", [](const GaussiansView& v) { return v.g->size(); })
      .def("__len__", [](const GaussiansView& v) { return v.g->size(); })
      .def_property_readonly("sh_degree", [](const GaussiansView& v) { return v.g->sh_degree; })
      .def_property_readonly("positions", [](py::object self) {
        const auto& g = *self.cast<const GaussiansView&>().g;
        return ArrayView(g.positions.data(), {Rows(g.positions.size(), 3), 3}, self);
      })
      .def_property_readonly("rotations", [](py::object self) {
        const auto& g = *self.cast<const GaussiansView&>().g;
        return ArrayView(g.rotations.data(), {Rows(g.rotations.size(), 4), 4}, self);
      })
      .def_property_readonly("log_scales", [](py::object self) {
        const auto& g = *self.cast<const GaussiansView&>().g;
        return ArrayView(g.log_scales.data(), {Rows(g.log_scales.size(), 3), 3}, self);
      })
      .def_property_readonly("opacity_logits", [](py::object self) {
        const auto& g = *self.cast<const GaussiansView&>().g;
        return ArrayView(g.opacity_logits.data(), {static_cast<py::ssize_t>(g.opacity_logits.size())}, self);
      })
      .def_property_readonly("sh", [](py::object self) {
        const auto& g = *self.cast<const GaussiansView&>().g;
        return ArrayView(g.sh.data(), {static_cast<py::ssize_t>(g.size()), g.sh_coeffs(), 3}, self);
      })
      .def_property_readonly(
          "time_windows",
          [](py::object self) -> py::object {
            const auto& g = *self.cast<const GaussiansView&>().g;
            if (!g.has_time_windows()) return py::none();
            return ArrayView(g.time_windows.data(), {static_cast<py::ssize_t>(g.size()), 2}, self);
          },
          "[N, 2] (centre time, inverse width) of time-local Gaussians (docs/conventions.md §3), or None "
          "when the asset has none; a deformed set has none (the window is applied to its opacity).")
      .def("tensors", [](const GaussiansView& v) { return GaussianTensors(v.g); },
           "The arrays as atex.Tensor objects (DLPack: torch.from_dlpack takes them without a copy), by name.")
      .def("__repr__", [](const GaussiansView& v) {
        return "atex.Gaussians(count=" + std::to_string(v.g->size()) + ", sh_degree=" +
               std::to_string(v.g->sh_degree) + ")";
      });
}

void RegisterTextures(py::module_& m) {
  py::class_<TexturesView>(m, "TexturePool",
                           "The packed texture pool (atex/model.h, BasicTexturePool), read-only numpy views:\n"
                           "  heights, widths [N] uint8 in {1, 2, 4}; axis_u, axis_v [N] uint8 canonical local axes;\n"
                           "  offsets [N + 1] uint64, first texel of Gaussian i (prefix sum of h * w);\n"
                           "  texels [texel_count, 4] float32 raw RGBA (before tanh); Gaussian i owns rows\n"
                           "  offsets[i] .. offsets[i+1] - 1, row-major over (v, u).")
      .def_property_readonly("heights", [](py::object self) {
        const auto& p = self.cast<const TexturesView&>().pool();
        return ArrayView(p.heights.data(), {static_cast<py::ssize_t>(p.heights.size())}, self);
      })
      .def_property_readonly("widths", [](py::object self) {
        const auto& p = self.cast<const TexturesView&>().pool();
        return ArrayView(p.widths.data(), {static_cast<py::ssize_t>(p.widths.size())}, self);
      })
      .def_property_readonly("axis_u", [](py::object self) {
        const auto& p = self.cast<const TexturesView&>().pool();
        return ArrayView(p.axis_u.data(), {static_cast<py::ssize_t>(p.axis_u.size())}, self);
      })
      .def_property_readonly("axis_v", [](py::object self) {
        const auto& p = self.cast<const TexturesView&>().pool();
        return ArrayView(p.axis_v.data(), {static_cast<py::ssize_t>(p.axis_v.size())}, self);
      })
      .def_property_readonly("offsets", [](py::object self) {
        const auto& p = self.cast<const TexturesView&>().pool();
        return ArrayView(p.offsets.data(), {static_cast<py::ssize_t>(p.offsets.size())}, self);
      })
      .def_property_readonly("texels", [](py::object self) {
        const auto& p = self.cast<const TexturesView&>().pool();
        return ArrayView(p.texels.data(), {Rows(p.texels.size(), 4), 4}, self);
      })
      .def_property_readonly("texel_count", [](const TexturesView& v) { return v.pool().texel_count(); })
      .def("histogram", [](const TexturesView& v) {
        const TextureHistogram h = ComputeTextureHistogram(v.pool());
        py::dict out;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) out[py::str(std::to_string(1 << a) + "x" + std::to_string(1 << b))] = h.counts[a][b];
        return out;
      }, "Gaussian counts per texture size, keyed 'HxW' (e.g. '1x4').");
}

py::tuple LinearViews(const Linear& l, py::handle owner) {
  return py::make_tuple(ArrayView(l.weight.data(), {l.out, l.in}, owner), ArrayView(l.bias.data(), {l.out}, owner));
}

void RegisterDeformation(py::module_& m) {
  py::class_<DeformationView>(m, "DeformationField",
                              "The HexPlane + MLP deformation field (atex/model.h, docs/conventions.md §3), as\n"
                              "read-only numpy views: planes[s][p] is [C, res_b, res_a] for scale s and plane p in\n"
                              "(xy, xz, xt, yz, yt, zt); trunk is a list of (weight [out, in], bias [out]); heads\n"
                              "has five entries (position, scale, rotation, opacity, sh), each None when the head is\n"
                              "off or two (weight, bias) layers.")
      .def_property_readonly("config", [](const DeformationView& v) {
        const DeformationConfig& c = v.field().config;
        py::dict d;
        d["channels"] = c.grid.channels;
        d["base_resolution"] = py::cast(c.grid.base_resolution);
        d["multires"] = py::cast(c.grid.multires);
        d["mlp_width"] = c.mlp_width;
        d["trunk_layers"] = c.trunk_layers;
        d["heads"] = py::cast(c.heads);
        d["sh_coeffs"] = c.sh_coeffs;
        d["aabb_lo"] = py::cast(c.aabb_lo);
        d["aabb_hi"] = py::cast(c.aabb_hi);
        d["time_scale"] = c.time_scale;
        d["time_offset"] = c.time_offset;
        return d;
      })
      .def_property_readonly("planes", [](py::object self) {
        const DeformationField& f = self.cast<const DeformationView&>().field();
        py::list scales;
        for (size_t s = 0; s < f.planes.size(); ++s) {
          py::list planes;
          for (int p = 0; p < kNumHexPlanes; ++p) {
            const int a = kHexPlaneAxes[p][0], b = kHexPlaneAxes[p][1];
            planes.append(ArrayView(f.planes[s][p].data(),
                               {f.config.grid.channels, f.config.grid.resolution(int(s), b),
                                f.config.grid.resolution(int(s), a)},
                               self));
          }
          scales.append(planes);
        }
        return scales;
      })
      .def_property_readonly("trunk", [](py::object self) {
        py::list out;
        for (const Linear& l : self.cast<const DeformationView&>().field().trunk) out.append(LinearViews(l, self));
        return out;
      })
      .def_property_readonly("heads", [](py::object self) {
        const DeformationField& f = self.cast<const DeformationView&>().field();
        py::list out;
        for (int h = 0; h < kNumDeformHeads; ++h) {
          if (!f.config.heads[h]) {
            out.append(py::none());
          } else {
            out.append(py::make_tuple(LinearViews(f.heads[h][0], self), LinearViews(f.heads[h][1], self)));
          }
        }
        return out;
      })
      .def_property_readonly("parameter_count", [](const DeformationView& v) { return ParameterCount(v.field()); });
}

StatusOr<ScalarEncoding> ParseEncoding(const std::string& name) {
  for (ScalarEncoding e : {ScalarEncoding::kFloat32, ScalarEncoding::kFloat16, ScalarEncoding::kQuant16,
                           ScalarEncoding::kQuant8}) {
    if (ScalarEncodingName(e) == name) return e;
  }
  return MakeError(StatusCode::kInvalidArgument, "unknown encoding '", name, "' (f32, f16, q16, q8)");
}

}  // namespace

// Write options from Python arguments (shared with atex.fit).
WriteOptions WriteOptionsFrom(const AssetHolder& holder, const std::string& codec, int zstd_level,
                              const py::object& encodings, bool keep_stats) {
  WriteOptions o = holder.file_encodings.value_or(WriteOptions{});
  o.zstd_level = zstd_level;
  o.write_stats = keep_stats;
  o.draco_positions = false;
  bool found = false;
  for (Codec c : {Codec::kRaw, Codec::kZstd, Codec::kShuffleZstd, Codec::kDeltaShuffleZstd}) {
    if (CodecName(c) == codec) {
      o.codec = c;
      found = true;
    }
  }
  if (codec == "draco") {  // Draco for positions, shuffle-zstd for the rest
    o.codec = Codec::kShuffleZstd;
    o.draco_positions = true;
    found = true;
  }
  if (!found) {
    ThrowStatus(MakeError(StatusCode::kInvalidArgument, "unknown codec '", codec,
                          "' (raw, zstd, shuffle-zstd, delta-shuffle-zstd, draco)"));
  }
  if (!encodings.is_none()) {
    for (auto item : encodings.cast<py::dict>()) {
      const std::string stream = py::str(item.first);
      bool known = false;
      for (int s = 0; s < static_cast<int>(fit::Stream::kCount); ++s) {
        if (stream == fit::StreamName(static_cast<fit::Stream>(s))) {
          fit::SetEncoding(&o, static_cast<fit::Stream>(s), ValueOrThrow(ParseEncoding(py::str(item.second))));
          known = true;
        }
      }
      if (!known) ThrowStatus(MakeError(StatusCode::kInvalidArgument, "encodings: unknown stream '", stream, "'"));
    }
  }
  return o;
}

py::dict EncodingsToPython(const WriteOptions& o) {
  py::dict out;
  for (int s = 0; s < static_cast<int>(fit::Stream::kCount); ++s) {
    out[fit::StreamName(static_cast<fit::Stream>(s))] =
        ScalarEncodingName(fit::GetEncoding(o, static_cast<fit::Stream>(s)));
  }
  return out;
}

AssetPtr DecodeBytes(const std::vector<uint8_t>& bytes, bool verify_checksums, const std::string& what) {
  auto holder = std::make_shared<AssetHolder>();
  Status status;
  {
    py::gil_scoped_release release;
    ReadOptions options;
    options.verify_checksums = verify_checksums;
    auto asset = DecodeAsset(bytes.data(), bytes.size(), options);
    if (asset.ok()) {
      holder->asset = std::move(*asset);
      auto encodings = fit::EncodingsOfFile(bytes.data(), bytes.size(), WriteOptions{});
      if (encodings.ok()) holder->file_encodings = *encodings;
    } else {
      status = what.empty() ? asset.status() : asset.status().WithContext(what);
    }
  }
  ThrowIfError(status);
  return holder;
}

AssetPtr ReadAsset(const std::string& path, const std::string& format, bool verify_checksums) {
  FileFormat f = FileFormat::kUnknown;
  if (!format.empty()) f = ValueOrThrow(ParseFileFormat(format));
  if (f == FileFormat::kUnknown) f = FileFormatFromPath(path);
  if (f == FileFormat::kAtex) {
    std::vector<uint8_t> bytes;
    {
      Status status;
      {
        py::gil_scoped_release release;
        auto read = ReadFileBytes(path);
        if (read.ok()) bytes = std::move(*read); else status = read.status().WithContext(path);
      }
      ThrowIfError(status);
    }
    return DecodeBytes(bytes, verify_checksums, path);
  }
  auto holder = std::make_shared<AssetHolder>();
  Status status;
  {
    py::gil_scoped_release release;
    auto asset = ReadAssetAs(path, f, ConvertOptions{});
    if (asset.ok()) holder->asset = std::move(*asset); else status = asset.status().WithContext(path);
  }
  ThrowIfError(status);
  return holder;
}

void RegisterAsset(py::module_& m) {
  RegisterGaussians(m);
  RegisterTextures(m);
  RegisterDeformation(m);

  py::class_<AssetHolder, AssetPtr>(m, "Asset",
                                    "An AdaTex4D asset (atex/model.h, Asset): canonical Gaussians, an optional texture\n"
                                    "pool, an optional deformation field, optional per-Gaussian statistics and the scene\n"
                                    "metadata. Immutable: its arrays are read-only numpy views of the C++ memory (no copy),\n"
                                    "and each view keeps the asset alive. New assets come from atex.read, atex.decode,\n"
                                    "atex.fit and atex.train.")
      .def_property_readonly("gaussian_count", [](const AssetHolder& a) { return a.asset.gaussians.size(); })
      .def("__len__", [](const AssetHolder& a) { return a.asset.gaussians.size(); })
      .def_property_readonly("sh_degree", [](const AssetHolder& a) { return a.asset.gaussians.sh_degree; })
      .def_property_readonly("gaussians", [](const AssetPtr& a) {
        return GaussiansView{GaussiansPtr(a, &a->asset.gaussians)};
      }, "The canonical Gaussians (atex.Gaussians: numpy views, no copy).")
      .def_property_readonly("textures", [](const AssetPtr& a) -> py::object {
        if (!a->asset.textures) return py::none();
        return py::cast(TexturesView{a});
      }, "The texture pool (atex.TexturePool), or None for plain 4DGS.")
      .def_property_readonly("deformation", [](const AssetPtr& a) -> py::object {
        if (!a->asset.deformation) return py::none();
        return py::cast(DeformationView{a});
      }, "The deformation field (atex.DeformationField), or None for a static scene.")
      .def_property_readonly("stats", [](py::object self) -> py::object {
        const auto& a = self.cast<const AssetHolder&>().asset;
        if (!a.stats) return py::none();
        const auto n = static_cast<py::ssize_t>(a.stats->size());
        py::dict d;
        d["texture_demand"] = ArrayView(a.stats->texture_demand.data(), {n}, self);
        d["peak_scale_u"] = ArrayView(a.stats->peak_scale_u.data(), {n}, self);
        d["peak_scale_v"] = ArrayView(a.stats->peak_scale_v.data(), {n}, self);
        d["importance"] = ArrayView(a.stats->importance.data(), {n}, self);
        return d;
      }, "Per-Gaussian statistics left by training for atex.fit (dict of [N] arrays), or None.")
      .def_property_readonly("metadata", [](const AssetHolder& a) { return JsonToPython(MetadataToJson(a.asset.metadata)); },
                             "The META chunk as a dict: bounds, time range, background, texture mode, provenance.")
      .def_property_readonly("time_range", [](const AssetHolder& a) {
        return py::make_tuple(a.asset.metadata.time_min, a.asset.metadata.time_max);
      })
      .def_property_readonly("file_encodings", [](const AssetHolder& a) -> py::object {
        if (!a.file_encodings) return py::none();
        return EncodingsToPython(*a.file_encodings);
      }, "Scalar encoding of each stream in the file the asset was read from (None when not read from .atex).")
      .def("deform", [](const AssetPtr& a, double t) {
        auto out = std::make_shared<Gaussians>();
        Status status;
        {
          py::gil_scoped_release release;
          if (a->asset.deformation) {
            status = DeformForward(*a->asset.deformation, a->asset.gaussians, t, out.get(), nullptr);
          } else {
            *out = a->asset.gaussians;
          }
        }
        ThrowIfError(status);
        return GaussiansView{out};
      }, py::arg("t"),
      "The Gaussians at scene time t (atex/deform.h, DeformForward): canonical + the residuals of the\n"
      "enabled heads. A static asset gives a copy of its canonical Gaussians. Runs on the CPU without the GIL.")
      .def("to_bytes", [](const AssetPtr& a, const std::string& codec, int zstd_level, py::object encodings,
                          bool keep_stats) {
        const WriteOptions o = WriteOptionsFrom(*a, codec, zstd_level, encodings, keep_stats);
        StatusOr<std::vector<uint8_t>> bytes = Status(StatusCode::kInternal, "not encoded");
        {
          py::gil_scoped_release release;
          bytes = EncodeAsset(a->asset, o);
        }
        const auto& b = ValueOrThrow(std::move(bytes));
        return py::bytes(reinterpret_cast<const char*>(b.data()), b.size());
      }, py::arg("codec") = "shuffle-zstd", py::arg("zstd_level") = 3, py::arg("encodings") = py::none(),
      py::arg("keep_stats") = true, "The .atex bytes (see write).")
      .def("write", [](const AssetPtr& a, const std::string& path, const std::string& codec, int zstd_level,
                       py::object encodings, bool keep_stats) {
        const WriteOptions o = WriteOptionsFrom(*a, codec, zstd_level, encodings, keep_stats);
        Status status;
        {
          py::gil_scoped_release release;
          status = WriteAssetFile(path, a->asset, o);
        }
        ThrowIfError(status);
      }, py::arg("path"), py::arg("codec") = "shuffle-zstd", py::arg("zstd_level") = 3,
      py::arg("encodings") = py::none(), py::arg("keep_stats") = true,
      "Writes the asset as .atex (atex/container.h, WriteAssetFile), atomically (temporary file + rename).\n\n"
      "codec: 'raw', 'zstd', 'shuffle-zstd' (default), 'delta-shuffle-zstd', or 'draco' (Draco positions,\n"
      "shuffle-zstd for the rest; needs a Draco build). encodings: {stream: 'f32'|'f16'|'q16'|'q8'} for the\n"
      "streams positions, rotations, log_scales, opacities, sh_dc, sh_rest, texels, deformation_grids; streams\n"
      "not named keep the encoding of the file the asset was read from (f32 otherwise). keep_stats: write the\n"
      "per-Gaussian statistics (GSTA). Writers are deterministic: the same asset and options give the same bytes.")
      .def("__repr__", [](const AssetHolder& a) {
        return "atex.Asset(gaussians=" + std::to_string(a.asset.gaussians.size()) + ", sh_degree=" +
               std::to_string(a.asset.gaussians.sh_degree) + ", textures=" + a.asset.metadata.texture_mode +
               ", deformation=" + (a.asset.deformation ? "yes" : "no") + ")";
      });

  m.def("read", &ReadAsset, py::arg("path"), py::arg("format") = "", py::arg("verify_checksums") = true,
        "Reads an asset. .atex files are decoded and checked in full (atex/container.h, ReadAssetFile: every\n"
        "structural rule, every CRC, every value; a file of another major format version raises atex.Error\n"
        "'unsupported-version'); other formats (.ply, .spz, 4DGaussians folders) go through the converters\n"
        "(format: 'ply', 'spz', 'atex', '4dgs'; default: from the extension). Hostile input raises atex.Error.");
  m.def("decode", [](py::bytes data, bool verify_checksums) {
    const std::string_view view = data;
    return DecodeBytes(std::vector<uint8_t>(view.begin(), view.end()), verify_checksums, "");
  }, py::arg("data"), py::arg("verify_checksums") = true, "Decodes .atex bytes (see read).");
}

}  // namespace atex::python
