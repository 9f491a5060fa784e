// Names, the lever list parser, the encodings of a file and the JSON of the fit report (fit.h).
#include <algorithm>
#include <cmath>
#include <map>

#include "atex/fit.h"

namespace atex::fit {

const char* LeverName(Lever lever) {
  switch (lever) {
    case Lever::kPrune: return "prune";
    case Lever::kTextures: return "textures";
    case Lever::kShDegree: return "sh";
    case Lever::kEncoding: return "encoding";
    case Lever::kGrid: return "grid";
    case Lever::kAllTextures: return "all-textures";
  }
  return "unknown";
}

namespace {
constexpr Lever kLevers[] = {Lever::kPrune, Lever::kTextures, Lever::kShDegree,
                             Lever::kEncoding, Lever::kGrid, Lever::kAllTextures};
}  // namespace

StatusOr<LeverSet> ParseLevers(const std::string& text) {
  if (text == "default") return kDefaultLevers;
  LeverSet set = 0;
  for (size_t start = 0; start <= text.size();) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string name = text.substr(start, comma - start);
    start = comma + 1;
    if (name.empty()) continue;
    bool known = false;
    for (Lever lever : kLevers) {
      if (name == LeverName(lever)) {
        set |= LeverBit(lever);
        known = true;
      }
    }
    if (!known) {
      return MakeError(StatusCode::kInvalidArgument, "unknown lever '", name, "' (known: ",
                       LeverSetNames(kAllLevers), ", or default)");
    }
  }
  if (set == 0) return MakeError(StatusCode::kInvalidArgument, "no lever named in '", text, "'");
  return set;
}

std::string LeverSetNames(LeverSet set) {
  std::string names;
  for (Lever lever : kLevers) {
    if (!HasLever(set, lever)) continue;
    if (!names.empty()) names += ",";
    names += LeverName(lever);
  }
  return names;
}

const char* StreamName(Stream stream) {
  switch (stream) {
    case Stream::kPositions: return "positions";
    case Stream::kRotations: return "rotations";
    case Stream::kLogScales: return "log_scales";
    case Stream::kOpacities: return "opacities";
    case Stream::kShDc: return "sh_dc";
    case Stream::kShRest: return "sh_rest";
    case Stream::kTexels: return "texels";
    case Stream::kDeformationGrids: return "deformation_grids";
    case Stream::kCount: break;
  }
  return "unknown";
}

namespace {
ScalarEncoding* EncodingField(WriteOptions* o, Stream stream) {
  switch (stream) {
    case Stream::kPositions: return &o->positions;
    case Stream::kRotations: return &o->rotations;
    case Stream::kLogScales: return &o->log_scales;
    case Stream::kOpacities: return &o->opacities;
    case Stream::kShDc: return &o->sh_dc;
    case Stream::kShRest: return &o->sh_rest;
    case Stream::kTexels: return &o->texels;
    default: return &o->deformation_grids;
  }
}
}  // namespace

ScalarEncoding GetEncoding(const WriteOptions& options, Stream stream) {
  WriteOptions copy = options;
  return *EncodingField(&copy, stream);
}
void SetEncoding(WriteOptions* options, Stream stream, ScalarEncoding encoding) {
  *EncodingField(options, stream) = encoding;
}

std::string DescribeMove(const Move& m) {
  switch (m.lever) {
    case Lever::kPrune: return StrCat("prune ", m.count, " Gaussians");
    case Lever::kTextures: return StrCat("shrink ", m.count, " texture axes");
    case Lever::kShDegree: return "lower the SH degree by one";
    case Lever::kEncoding: return StrCat("store ", StreamName(m.stream), " as ", ScalarEncodingName(m.encoding));
    case Lever::kGrid: return "halve the deformation grid resolution";
    case Lever::kAllTextures: return "halve the longer axis of every texture";
  }
  return "unknown move";
}

nlohmann::json TimingToJson(const MeasureTiming& t) {
  const double per = t.measurements > 0 ? 1.0 / t.measurements : 0.0;
  // Apply, encode and decode were paid by unused speculative preparations and next steps too
  // (those cancelled before they started paid nothing: an upper bound).
  const int prepared = t.measurements + t.prepared_unused + (t.next_steps_prepared - t.next_steps_used);
  const double per_prepared = prepared > 0 ? 1.0 / prepared : 0.0;
  const double parts = t.apply_seconds + t.encode_seconds + t.decode_seconds + t.render_state_seconds +
                       t.render_seconds +
                       t.distortion_seconds + t.reference_seconds + t.propose_seconds - t.overlap_seconds;
  return {{"measurements", t.measurements},
          {"prepared_ahead", t.prepared_ahead},
          {"prepared_unused", t.prepared_unused},
          {"next_steps_prepared", t.next_steps_prepared},
          {"next_steps_used", t.next_steps_used},
          {"seconds",
           {{"apply", t.apply_seconds},
            {"encode", t.encode_seconds},
            {"decode", t.decode_seconds},
            {"render_state", t.render_state_seconds},
            {"render", t.render_seconds},
            {"render_load", t.render_load_seconds},
            {"distortion", t.distortion_seconds},
            {"reference", t.reference_seconds},
            {"propose", t.propose_seconds},
            {"overlap", t.overlap_seconds},
            {"other", std::max(0.0, t.total_seconds - parts)},
            {"total", t.total_seconds}}},
          {"seconds_per_measurement",
           {{"apply", t.apply_seconds * per_prepared},
            {"encode", t.encode_seconds * per_prepared},
            {"decode", t.decode_seconds * per_prepared},
            {"render_state", t.render_state_seconds * per_prepared},
            {"render", t.render_seconds * per},
            {"distortion", t.distortion_seconds * per}}},
          {"probe_cache",
           {{"deformed", t.probe_cache.deformed},
            {"deform_reused", t.probe_cache.deform_reused},
            {"tiles_drawn", t.probe_cache.tiles_drawn},
            {"tiles_reused", t.probe_cache.tiles_reused}}}};
}

nlohmann::json MoveToJson(const Move& m) {
  nlohmann::json j = {{"lever", LeverName(m.lever)},
                      {"what", DescribeMove(m)},
                      {"bytes_after", m.bytes_after},
                      {"distortion_after", m.distortion_after},
                      {"proxy_psnr_after", m.distortion_after > 0 ? -10.0 * std::log10(m.distortion_after) : 99.0}};
  if (m.divisible()) j["count"] = m.count;
  if (m.lever == Lever::kEncoding) {
    j["stream"] = StreamName(m.stream);
    j["encoding"] = ScalarEncodingName(m.encoding);
  }
  return j;
}

nlohmann::json ComponentsToJson(const std::vector<uint8_t>& encoded) {
  nlohmann::json j = nlohmann::json::object();
  auto info = InspectContainer(encoded.data(), encoded.size());
  if (!info.ok()) return j;
  for (const ComponentSize& c : ComponentBytes(*info)) j[c.component] = c.bytes;
  return j;
}

StatusOr<WriteOptions> EncodingsOfFile(const uint8_t* data, size_t size, const WriteOptions& base) {
  ATEX_ASSIGN_OR_RETURN(ContainerInfo info, InspectContainer(data, size));
  WriteOptions out = base;
  static const std::map<std::string, Stream> kStreams = {
      {"GPOS", Stream::kPositions}, {"GROT", Stream::kRotations}, {"GSCL", Stream::kLogScales},
      {"GOPA", Stream::kOpacities}, {"GSH0", Stream::kShDc},      {"GSHR", Stream::kShRest},
      {"TEXL", Stream::kTexels},    {"DGRD", Stream::kDeformationGrids}};
  for (const ChunkInfo& chunk : info.chunks) {
    const auto it = kStreams.find(chunk.type);
    if (it == kStreams.end()) continue;
    if (chunk.codec == Codec::kDraco) continue;  // Draco positions: re-encoded with `base`'s settings
    ATEX_ASSIGN_OR_RETURN(ScalarEncoding e, StreamEncodingOf(data, size, chunk));
    SetEncoding(&out, it->second, e);
  }
  return out;
}

}  // namespace atex::fit
