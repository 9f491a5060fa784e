// `atex convert IN OUT`: between .ply, .spz, .atex, .exr (texture atlas) and .drc,
// from a 4DGaussians output folder, and per-frame .ply/.spz export (--frames).
// Thin front end over atex/converters/convert.h.
#include <cstdio>
#include <memory>
#include <string>

#include "atex/converters/convert.h"
#include "cli.h"
#include "cli_parse.h"

namespace {

struct ConvertArgs {
  std::string input, output;
  std::string from, to;
  std::string spz_axes = "opencv";
  int spz_version = 4;
  int draco_bits = 16;
  bool draco_attributes = false;
  double time = 0;
  bool has_time = false;
  bool bake_textures = false;
  std::string base;
  int atlas_width = 0;
  std::string codec = "shuffle-zstd";
  std::string encoding = "f32";
  int zstd_level = 3;
  std::string frames;  // START:END:STEP; empty: one output file
  int iteration = -1;  // 4dgs input: -1 = the highest
  bool json = false, force = false;
};

// The output's extension names the format written (--to, when given, must agree with it).
atex::Status CheckConvertOutput(const ConvertArgs& a) {
  if (!a.frames.empty()) return atex::cli::CheckOutput(a.output, a.force, {{a.input}, {}, "output folder", true, true});
  std::vector<std::string> extensions = {".ply", ".spz", ".atex", ".exr", ".drc"};
  if (!a.to.empty()) {
    std::string to = a.to;
    for (char& c : to) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    extensions = {"." + to};
  }
  return atex::cli::CheckOutput(a.output, a.force, {{a.input, a.base}, extensions});
}

atex::StatusOr<atex::Codec> ParseCodec(const std::string& name) {
  if (name == "raw") return atex::Codec::kRaw;
  if (name == "zstd") return atex::Codec::kZstd;
  if (name == "shuffle-zstd") return atex::Codec::kShuffleZstd;
  if (name == "delta-shuffle-zstd") return atex::Codec::kDeltaShuffleZstd;
  return atex::MakeError(atex::StatusCode::kInvalidArgument, "unknown --codec '", name,
                         "' (raw, zstd, shuffle-zstd, delta-shuffle-zstd)");
}

atex::StatusOr<atex::ScalarEncoding> ParseEncoding(const std::string& name) {
  if (name == "f32") return atex::ScalarEncoding::kFloat32;
  if (name == "f16") return atex::ScalarEncoding::kFloat16;
  if (name == "q16") return atex::ScalarEncoding::kQuant16;
  if (name == "q8") return atex::ScalarEncoding::kQuant8;
  return atex::MakeError(atex::StatusCode::kInvalidArgument, "unknown --encoding '", name, "' (f32, f16, q16, q8)");
}

int RunConvert(const ConvertArgs& a) {
  atex::ConvertOptions options;
  if (!a.from.empty()) {
    auto f = atex::ParseFileFormat(a.from);
    if (!f.ok()) return atex::cli::Fail("convert", f.status());
    options.from = *f;
  }
  if (!a.to.empty()) {
    auto f = atex::ParseFileFormat(a.to);
    if (!f.ok()) return atex::cli::Fail("convert", f.status());
    options.to = *f;
  }
  options.spz_axes = a.spz_axes == "stored" ? atex::SpzAxes::kStored : atex::SpzAxes::kOpenCv;
  options.spz_version = a.spz_version;
  options.draco_bits = a.draco_bits;
  options.draco_attributes = a.draco_attributes;
  if (a.has_time) options.time = a.time;
  options.bake_textures = a.bake_textures;
  options.base_asset = a.base;
  options.atlas_width = a.atlas_width;
  options.fourdgs.iteration = a.iteration;
  if (!a.frames.empty()) {
    auto range = atex::ParseFrameRange(a.frames);
    if (!range.ok()) return atex::cli::Fail("convert", range.status());
    options.frames = *range;
  }
  // Drawn only once frames are being written (reading a large asset comes first).
  std::unique_ptr<atex::cli::Progress> bar;
  options.frame_progress = [&bar](size_t done, size_t total) {
    if (!bar) bar = std::make_unique<atex::cli::Progress>("convert frames", static_cast<long long>(total));
    if (done < total) bar->Update(static_cast<long long>(done));  // Finish() draws the end
    return true;
  };
  auto codec = ParseCodec(a.codec);
  if (!codec.ok()) return atex::cli::Fail("convert", codec.status());
  options.atex.codec = *codec;
  options.atex.zstd_level = a.zstd_level;
  auto encoding = ParseEncoding(a.encoding);
  if (!encoding.ok()) return atex::cli::Fail("convert", encoding.status());
  auto& w = options.atex;
  w.positions = w.rotations = w.log_scales = w.opacities = w.sh_dc = w.sh_rest = w.texels = w.deformation_grids =
      *encoding;

  if (atex::Status s = CheckConvertOutput(a); !s.ok()) return atex::cli::Fail("convert", s, a.output);
  auto report = atex::ConvertFile(a.input, a.output, options);
  if (!report.ok()) {
    if (bar && bar->tty()) std::fputc('\n', stderr);  // end the progress line before the message
    return atex::cli::Fail("convert", report.status());
  }
  if (bar) bar->Finish();
  // Warnings also go to stderr so that they are seen when stdout is parsed (--json).
  for (const auto& warning : report->warnings) std::fprintf(stderr, "atex convert: warning: %s\n", warning.c_str());
  if (a.json) {
    atex::cli::PrintJson(report->ToJson());
  } else {
    const size_t frames = report->frame_times.size();
    char deform[48] = "";  // only when something was deformed
    if (frames > 0 || report->time.has_value()) {
      std::snprintf(deform, sizeof deform, "deform %.3f s, ", report->convert_seconds);
    }
    std::printf("%s -> %s%s: %llu Gaussians (SH %d), %llu -> %llu bytes (%.2f bytes/Gaussian%s), read %.3f s, "
                "%swrite %.3f s\n",
                std::string(atex::FileFormatName(report->from)).c_str(),
                std::string(atex::FileFormatName(report->to)).c_str(),
                frames ? (" x " + std::to_string(frames) + " frames in " + a.output).c_str() : "",
                static_cast<unsigned long long>(report->gaussians), report->sh_degree,
                static_cast<unsigned long long>(report->input_bytes),
                static_cast<unsigned long long>(report->output_bytes),
                report->gaussians
                    ? double(report->output_bytes) / double(report->gaussians) / double(frames ? frames : 1)
                    : 0.0,
                frames ? " per frame" : "", report->read_seconds, deform, report->write_seconds);
    for (const auto& d : report->dropped) std::printf("  dropped: %s (the output format cannot hold it)\n", d.c_str());
    for (const auto& n : report->notes) std::printf("  note: %s\n", n.c_str());
  }
  return atex::cli::kExitOk;
}

atex::cli::Runner SetupConvert(CLI::App& app) {
  auto a = std::make_shared<ConvertArgs>();
  app.add_option("input", a->input,
                 "Input file (.ply incl. .compressed.ply, .spz, .atex, .exr, .splat, .ksplat, .sog or a SOG "
                 "meta.json), or a 4DGaussians output folder (the run folder, whose "
                 "highest point_cloud/iteration_N is read, or one iteration folder holding point_cloud.ply and "
                 "deformation.pth)")
      ->required();
  app.add_option("output", a->output, "Output file (.ply, .spz, .atex, .exr, .drc), or a folder with --frames")
      ->required();
  app.add_option("--from", a->from, "Input format when the extension does not say it (4dgs: a 4DGaussians folder)")
      ->check(CLI::IsMember({"ply", "spz", "atex", "exr", "drc", "4dgs", "splat", "ksplat", "sog"}, CLI::ignore_case));
  app.add_option("--to", a->to,
                 "Output format when the extension does not say it (with --frames: ply or spz, default ply)")
      ->check(CLI::IsMember({"ply", "spz", "atex", "exr", "drc"}, CLI::ignore_case));
  app.add_option("--spz-version", a->spz_version,
                 "SPZ version to write (default 4, the current one; 3 for readers that have no version 4 yet, "
                 "e.g. three.js Spark 2.2)")
      ->check(CLI::IsMember({3, 4}));
  app.add_option("--spz-axes", a->spz_axes,
                 "opencv: convert SPZ's RUB axes to/from libatex's RDF world; stored: keep the file's axes")
      ->check(CLI::IsMember({"opencv", "stored"}));
  app.add_option("--draco-bits", a->draco_bits, "Draco position quantisation bits")->check(CLI::Range(1, 30));
  app.add_flag("--draco-attributes", a->draco_attributes, "Also store colour, opacity, log-scale and rotation");
  atex::cli::AddReal(app, "--time", &a->time, -1e9, 1e9,
                     "Deform to this scene time for .ply/.spz/.drc output (whole field: every enabled head)")
      ->each([a](const std::string&) { a->has_time = true; });
  app.add_flag("--bake-textures", a->bake_textures,
               ".ply/.spz/.drc output: bake each textured Gaussian into 1-4 plain Gaussians instead of dropping "
               "the textures");
  app.add_option("--base", a->base, ".exr input: the asset (.atex/.ply/.spz) whose textures the atlas replaces");
  app.add_option("--atlas-width", a->atlas_width, ".exr output: atlas width in texels (0: square-ish)")
      ->check(CLI::Range(0, 1 << 20));
  app.add_option("--codec", a->codec, ".atex output: chunk codec (raw, zstd, shuffle-zstd, delta-shuffle-zstd)");
  app.add_option("--encoding", a->encoding, ".atex output: every attribute stream as f32, f16, q16 or q8")
      ->check(CLI::IsMember({"f32", "f16", "q16", "q8"}));
  app.add_option("--zstd-level", a->zstd_level, ".atex output: zstd level")->check(CLI::Range(1, 22));
  app.add_option("--frames", a->frames,
                 "START:END:STEP (scene time units, END inclusive, e.g. 0:1:0.1 -> 11 frames): write the Gaussians "
                 "deformed at each time (every enabled head, opacity and SH included) as OUTPUT/frame_0000.ply ... "
                 "(--to spz for .spz) and OUTPUT/frames.json with each file's time; textures are left out")
      ->excludes("--time");
  app.add_option("--iteration", a->iteration,
                 "4DGaussians input: import point_cloud/iteration_N (default: the highest)")
      ->check(CLI::Range(0, 1 << 30));
  atex::cli::AddForceFlag(app, &a->force);
  app.add_flag("--json", a->json, "Print a machine-readable summary");
  return [a]() { return RunConvert(*a); };
}

ATEX_REGISTER_COMMAND("convert",
                      "Convert between .ply, .spz, .atex, .exr (texture atlas) and .drc, import a 4DGaussians run, "
                      "or export per-frame .ply/.spz (--frames)",
                      SetupConvert);

}  // namespace
