// `atex view` page assembly: choose the Gaussians and keyframes within the size cap, bake
// (view_bake.cc), and put the payload (JSON with base64 arrays) into the page template
// compiled into the library (view_template.html through the generated view_template.h).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "atex/converters/view.h"
#include "atex/file_io.h"
#include "atex/render.h"
#include "splatv/half.h"
#include "view/view_bake.h"
#include "view/view_codec.h"
#include "view/view_template.h"

namespace atex {
namespace {

constexpr std::string_view kDataMarker = "/*ATEX_VIEW_DATA*/";
constexpr std::string_view kTitleMarker = "<!--ATEX_VIEW_TITLE-->";
constexpr std::string_view kDataOpen = "<script type=\"application/json\" id=\"atex-view-data\">";
constexpr char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

std::string Base64(const uint8_t* data, size_t size) {
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 3 <= size; i += 3) {
    const uint32_t v = uint32_t(data[i]) << 16 | uint32_t(data[i + 1]) << 8 | data[i + 2];
    for (int s = 18; s >= 0; s -= 6) out.push_back(kBase64[(v >> s) & 63]);
  }
  if (i < size) {
    const uint32_t v = uint32_t(data[i]) << 16 | (i + 1 < size ? uint32_t(data[i + 1]) << 8 : 0);
    out.push_back(kBase64[(v >> 18) & 63]);
    out.push_back(kBase64[(v >> 12) & 63]);
    out.push_back(i + 1 < size ? kBase64[(v >> 6) & 63] : '=');
    out.push_back('=');
  }
  return out;
}

StatusOr<std::vector<uint8_t>> FromBase64(std::string_view text, std::string_view what) {
  if (text.size() % 4 != 0)
    return MakeError(StatusCode::kCorrupt, "view payload: ", what, ": base64 length ", text.size(),
                     " is not a multiple of 4");
  std::vector<uint8_t> out;
  out.reserve(text.size() / 4 * 3);
  for (size_t i = 0; i < text.size(); i += 4) {
    uint32_t v = 0;
    int pad = 0;
    for (size_t k = 0; k < 4; ++k) {
      const char c = text[i + k];
      int d = -1;
      if (c >= 'A' && c <= 'Z') d = c - 'A';
      else if (c >= 'a' && c <= 'z') d = c - 'a' + 26;
      else if (c >= '0' && c <= '9') d = c - '0' + 52;
      else if (c == '+') d = 62;
      else if (c == '/') d = 63;
      else if (c == '=' && i + 4 == text.size() && k >= 2 && (k == 3 || text[i + 3] == '=')) d = 0, ++pad;
      if (d < 0 || (pad > 0 && c != '=')) {
        return MakeError(StatusCode::kCorrupt, "view payload: ", what, ": invalid base64 character at offset ", i + k);
      }
      v = v << 6 | uint32_t(d);
    }
    out.push_back(uint8_t(v >> 16));
    if (pad < 2) out.push_back(uint8_t(v >> 8));
    if (pad < 1) out.push_back(uint8_t(v));
  }
  return out;
}

template <typename T>
StatusOr<nlohmann::json> ArrayJson(const std::vector<T>& values, std::string_view type, int components, int frames,
                                   bool compress, uint64_t* stored_bytes) {
  const auto* bytes = reinterpret_cast<const uint8_t*>(values.data());
  nlohmann::json a = {{"type", type}, {"components", components}, {"frames", frames}};
  if (compress) {
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> packed,
                          view::CompressArray(bytes, sizeof(T), values.size() / size_t(frames), size_t(frames)));
    a["encoding"] = view::kCompressedEncoding;
    a["data"] = Base64(packed.data(), packed.size());
    *stored_bytes += packed.size();
  } else {
    a["encoding"] = "raw";
    a["data"] = Base64(bytes, values.size() * sizeof(T));
    *stored_bytes += values.size() * sizeof(T);
  }
  return a;
}

// JSON inside <script>: no "</script" can appear once every '<' is escaped.
std::string ScriptSafe(const std::string& json) {
  std::string out;
  out.reserve(json.size());
  for (char c : json) {
    if (c == '<') out += "\\u003c";
    else out.push_back(c);
  }
  return out;
}

std::string HtmlEscape(std::string_view text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out.push_back(c);
    }
  }
  return out;
}

nlohmann::json CameraJson(const Camera& c) {
  return {{"width", c.width}, {"height", c.height}, {"fx", c.fx}, {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy},
          {"world_to_camera", c.world_to_camera}};
}

// The orbit centre for a given camera: the point of its optical axis nearest `centre`
// (at least a tenth of the distance to it in front of the camera).
std::array<double, 3> OrbitTarget(const Camera& c, const std::array<double, 3>& centre) {
  const auto eye = c.Center();
  const std::array<double, 3> forward = {c.world_to_camera[8], c.world_to_camera[9], c.world_to_camera[10]};
  double along = 0, dist = 0;
  for (int k = 0; k < 3; ++k) {
    along += (centre[size_t(k)] - eye[size_t(k)]) * forward[size_t(k)];
    dist += (centre[size_t(k)] - eye[size_t(k)]) * (centre[size_t(k)] - eye[size_t(k)]);
  }
  along = std::max(along, 0.1 * std::sqrt(dist) + 1e-6);
  return {eye[0] + along * forward[0], eye[1] + along * forward[1], eye[2] + along * forward[2]};
}

Status CheckCamera(const Camera& c) {
  if (c.width <= 0 || c.height <= 0 || !(c.fx > 0) || !(c.fy > 0) || !std::isfinite(c.cx) || !std::isfinite(c.cy)) {
    return MakeError(StatusCode::kInvalidArgument, "view: the camera needs a positive size and focal lengths (",
                     c.width, "x", c.height, ", fx ", c.fx, ", fy ", c.fy, ")");
  }
  for (double v : c.world_to_camera) {
    if (!std::isfinite(v))
      return MakeError(StatusCode::kInvalidArgument, "view: the camera's world_to_camera is not finite");
  }
  return Status::Ok();
}

// What the page shows differently from the asset (the payload's "approximations").
nlohmann::json Approximations(const Asset& asset, int frames) {
  nlohmann::json out = nlohmann::json::array();
  if (asset.gaussians.sh_degree > 0) {
    out.push_back(StrCat("colour: the DC term only (the asset's view-dependent SH of degree ",
                         asset.gaussians.sh_degree, " is dropped)"));
  }
  if (asset.textures) {
    out.push_back("textures: each Gaussian's texture is replaced by its average (colour + 0.1 mean tanh(rgb), "
                  "opacity x mean exp(0.1 tanh(a)))");
  }
  if (frames > 1) out.push_back("motion: interpolated linearly between keyframes");
  return out;
}

// The template with its title and payload markers replaced.
StatusOr<std::string> FillTemplate(const std::string& title, const std::string& json) {
  const std::string_view page = ViewTemplate();
  const size_t data_at = page.find(kDataMarker), title_at = page.find(kTitleMarker);
  if (data_at == std::string_view::npos || title_at == std::string_view::npos || title_at > data_at) {
    return MakeError(StatusCode::kInternal, "view: the page template lacks its markers");
  }
  std::string html;
  html.reserve(page.size() + json.size() + title.size());
  html.append(page.substr(0, title_at));
  html.append(HtmlEscape(title));
  html.append(page.substr(title_at + kTitleMarker.size(), data_at - title_at - kTitleMarker.size()));
  html.append(json);
  html.append(page.substr(data_at + kDataMarker.size()));
  return html;
}

}  // namespace

std::string_view ViewTemplate() { return view::kViewTemplate; }

nlohmann::json ViewReport::ToJson() const {
  return {{"gaussians", gaussians},
          {"kept", kept},
          {"frames", times.size()},
          {"frames_requested", frames_requested},
          {"times", times},
          {"dynamic", dynamic},
          {"payload_bytes", payload_bytes},
          {"stored_bytes", stored_bytes},
          {"bytes", html_bytes},
          {"up", up},
          {"camera", CameraJson(camera)},
          {"target", target},
          {"warnings", warnings},
          {"notes", notes}};
}

StatusOr<std::string> EncodeViewHtml(const Asset& asset, const ViewOptions& options, ViewReport* report) {
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  if (asset.gaussians.size() == 0) return MakeError(StatusCode::kInvalidArgument, "view: the asset has no Gaussians");
  if (options.frames < 0 || options.frames > kViewMaxFrames) {
    return MakeError(StatusCode::kInvalidArgument, "view: frames = ", options.frames, " (need 0 .. ", kViewMaxFrames,
                     ")");
  }
  if (options.camera) ATEX_RETURN_IF_ERROR(CheckCamera(*options.camera));
  ViewReport r;
  r.gaussians = asset.gaussians.size();
  UpAxis up = UpAxis::kNegY;
  if (options.up) {
    up = *options.up;
  } else if (auto recorded = UpAxisOf(asset.metadata); recorded.ok()) {
    up = *recorded;
  } else {
    r.notes.push_back("the asset does not record its up axis: -y (the 3DGS convention) is up");
  }
  r.up = UpAxisName(up);

  const std::vector<uint32_t> kept = view::KeptGaussians(asset.gaussians, options.max_splats);
  r.kept = kept.size();
  if (kept.size() > kViewMaxSplats) {
    return MakeError(StatusCode::kLimitExceeded, "view: ", kept.size(), " Gaussians are more than the page can hold (",
                     kViewMaxSplats, ", WebGL2's guaranteed texture size); keep fewer (max_splats)");
  }
  if (kept.size() < asset.gaussians.size()) {
    r.notes.push_back(StrCat("kept the ", kept.size(), " of ", asset.gaussians.size(),
                             " Gaussians with the largest opacity x volume"));
  }
  // Keyframes within the size cap: the template, the JSON around the arrays and the
  // arrays' base64 (4 characters per 3 bytes).
  const bool moving = asset.deformation.has_value();
  const int requested = moving ? (options.frames > 0 ? options.frames : DefaultViewFrames(asset)) : 1;
  r.frames_requested = moving ? requested : 0;
  const view::Dynamic dyn = view::DynamicArrays(asset);
  const uint64_t fixed_bytes = ViewTemplate().size() + 4096 + 32 * uint64_t(std::max(requested, 1));
  // (Uncompressed, plus deflate's worst-case growth: an upper bound of the compressed page too.)
  auto html_estimate = [&](int frames) {
    const uint64_t raw = view::PayloadBytes(dyn, kept.size(), frames);
    return fixed_bytes + (raw + raw / 500 + 4 * 64 + 2) / 3 * 4 + 16;
  };
  int frames = requested;
  while (frames > (moving ? 2 : 1) && html_estimate(frames) > options.max_bytes) --frames;
  if (html_estimate(frames) > options.max_bytes) {
    return MakeError(StatusCode::kBudgetTooSmall, "view: ", frames, " keyframe(s) of ", kept.size(),
                     " Gaussians need about ", html_estimate(frames), " bytes, over the cap of ", options.max_bytes,
                     "; raise the cap or keep fewer Gaussians (max_splats)");
  }
  if (frames < requested) {
    r.notes.push_back(
        StrCat(requested, " keyframes requested, ", frames, " fit the cap of ", options.max_bytes, " bytes"));
  }
  const double t0 = asset.metadata.time_min, t1 = asset.metadata.time_max;
  for (int k = 0; k < frames; ++k) {
    r.times.push_back(frames == 1 ? (moving ? t0 : 0.5 * (t0 + t1)) : t0 + (t1 - t0) * double(k) / double(frames - 1));
  }

  Gaussians first;
  ATEX_ASSIGN_OR_RETURN(ViewPayload payload, view::BakeKeyframes(asset, kept, r.times, options, &first));
  if (payload.position_frames > 1) r.dynamic.push_back("positions");
  if (payload.rotation_frames > 1) r.dynamic.push_back("rotations");
  if (payload.scale_frames > 1) r.dynamic.push_back("log_scales");
  if (payload.colour_frames > 1) r.dynamic.push_back("colours");

  std::array<double, 3> centre;
  r.camera = DefaultViewCamera(first, up, 960, 720, &centre);
  r.target = centre;
  if (options.camera) {
    r.camera = *options.camera;
    r.target = OrbitTarget(r.camera, centre);
  }

  const nlohmann::json approximations = Approximations(asset, frames);
  for (const auto& a : approximations) r.warnings.push_back(a.get<std::string>());
  const auto& bg = asset.metadata.background;
  nlohmann::json data = {
      {"format", "atex-view"},
      {"version", 1},
      {"title", options.title},
      {"count", payload.count},
      {"times", payload.times},
      {"up", r.up},
      {"up_vector", view::ViewUpVector(up)},
      {"background", {bg[0], bg[1], bg[2]}},
      {"near", kDefaultNearPlane},
      {"camera", CameraJson(r.camera)},
      {"target", r.target},
      {"position_lo", payload.position_lo},
      {"position_hi", payload.position_hi},
      {"colour_range", payload.colour_range},
      {"opacity_scale", payload.opacity_scale},
      {"approximations", approximations},
      {"source",
       {{"gaussians", r.gaussians}, {"time_min", t0}, {"time_max", t1}, {"texture_mode", asset.metadata.texture_mode}}},
      {"arrays", nlohmann::json::object()}};
  const bool z = options.compress;
  auto& arrays = data["arrays"];
  ATEX_ASSIGN_OR_RETURN(arrays["positions"],
                        ArrayJson(payload.positions, "u16", 3, payload.position_frames, z, &r.stored_bytes));
  ATEX_ASSIGN_OR_RETURN(arrays["rotations"],
                        ArrayJson(payload.rotations, "i8", 4, payload.rotation_frames, z, &r.stored_bytes));
  ATEX_ASSIGN_OR_RETURN(arrays["log_scales"],
                        ArrayJson(payload.log_scales, "f16", 3, payload.scale_frames, z, &r.stored_bytes));
  ATEX_ASSIGN_OR_RETURN(arrays["colours"],
                        ArrayJson(payload.colours, "u8", 4, payload.colour_frames, z, &r.stored_bytes));
  r.payload_bytes = payload.positions.size() * 2 + payload.rotations.size() + payload.log_scales.size() * 2 +
                    payload.colours.size();

  ATEX_ASSIGN_OR_RETURN(std::string html, FillTemplate(options.title, ScriptSafe(data.dump())));
  r.html_bytes = html.size();
  if (html.size() > options.max_bytes) {
    return MakeError(StatusCode::kInternal, "view: the page of ", html.size(), " bytes exceeds its estimate's cap of ",
                     options.max_bytes);
  }
  if (report) *report = std::move(r);
  return html;
}

Status WriteViewHtml(const std::string& path, const Asset& asset, const ViewOptions& options, ViewReport* report) {
  ATEX_ASSIGN_OR_RETURN(std::string html, EncodeViewHtml(asset, options, report));
  return WriteFileAtomic(path, html.data(), html.size());
}

StatusOr<ViewPayload> DecodeViewHtml(std::string_view html) {
  const size_t open = html.find(kDataOpen);
  if (open == std::string_view::npos) return MakeError(StatusCode::kBadMagic, "view page: no atex-view-data element");
  const size_t begin = open + kDataOpen.size();
  const size_t end = html.find("</script>", begin);
  if (end == std::string_view::npos)
    return MakeError(StatusCode::kTruncated, "view page: the payload element is not closed (byte ", begin, ")");
  nlohmann::json data = nlohmann::json::parse(html.substr(begin, end - begin), nullptr, false);
  if (data.is_discarded() || !data.is_object())
    return MakeError(StatusCode::kCorrupt, "view page: the payload at byte ", begin, " is not JSON");
  ViewPayload p;
  try {
    if (data.at("format") != "atex-view" || data.at("version") != 1) {
      return MakeError(StatusCode::kCorrupt, "view page: the payload is not atex-view version 1");
    }
    p.count = data.at("count").get<size_t>();
    p.times = data.at("times").get<std::vector<double>>();
    p.position_lo = data.at("position_lo").get<std::array<float, 3>>();
    p.position_hi = data.at("position_hi").get<std::array<float, 3>>();
    p.colour_range = data.at("colour_range").get<std::array<float, 2>>();
    p.opacity_scale = data.at("opacity_scale").get<float>();
    if (p.count > html.size())
      return MakeError(StatusCode::kCorrupt, "view page: count ", p.count, " exceeds the page's size");
    if (p.times.empty()) return MakeError(StatusCode::kCorrupt, "view page: no keyframe times");
    auto read = [&](const char* name, const char* type, int components, int* frames, auto* out) -> Status {
      const nlohmann::json& a = data.at("arrays").at(name);
      *frames = a.at("frames").get<int>();
      if (a.at("type") != type || a.at("components") != components ||
          (*frames != 1 && size_t(*frames) != p.times.size())) {
        return MakeError(StatusCode::kCorrupt, "view page: array ", name, " has type ", a.at("type").dump(), ", ",
                         a.at("components").dump(), " components, ", *frames, " frames");
      }
      ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, FromBase64(a.at("data").get_ref<const std::string&>(), name));
      using T = typename std::remove_pointer_t<decltype(out)>::value_type;
      const size_t expected = size_t(*frames) * p.count * size_t(components);
      const std::string encoding = a.value("encoding", std::string("raw"));
      if (encoding == view::kCompressedEncoding) {
        ATEX_ASSIGN_OR_RETURN(bytes, view::DecompressArray(bytes, sizeof(T), p.count * size_t(components),
                                                           size_t(*frames), expected * sizeof(T)));
      } else if (encoding != "raw") {
        return MakeError(StatusCode::kCorrupt, "view page: array ", name, " has the unknown encoding '", encoding, "'");
      }
      if (bytes.size() != expected * sizeof(T)) {
        return MakeError(StatusCode::kCorrupt, "view page: array ", name, " holds ", bytes.size(), " bytes, expected ",
                         expected * sizeof(T));
      }
      out->resize(expected);
      std::memcpy(out->data(), bytes.data(), bytes.size());
      return Status::Ok();
    };
    ATEX_RETURN_IF_ERROR(read("positions", "u16", 3, &p.position_frames, &p.positions));
    ATEX_RETURN_IF_ERROR(read("rotations", "i8", 4, &p.rotation_frames, &p.rotations));
    ATEX_RETURN_IF_ERROR(read("log_scales", "f16", 3, &p.scale_frames, &p.log_scales));
    ATEX_RETURN_IF_ERROR(read("colours", "u8", 4, &p.colour_frames, &p.colours));
  } catch (const nlohmann::json::exception& e) {
    return MakeError(StatusCode::kCorrupt, "view page: payload field missing or of the wrong type: ", e.what());
  }
  data.erase("arrays");
  p.header = std::move(data);
  return p;
}

std::array<float, 3> ViewPayload::Position(size_t k, size_t i) const {
  k = std::min(k, size_t(position_frames - 1));
  std::array<float, 3> out;
  for (size_t c = 0; c < 3; ++c) {
    out[c] = position_lo[c] + float(positions[(k * count + i) * 3 + c]) * (position_hi[c] - position_lo[c]) / 65535.0f;
  }
  return out;
}

std::array<float, 4> ViewPayload::Rotation(size_t k, size_t i) const {
  k = std::min(k, size_t(rotation_frames - 1));
  std::array<float, 4> out;
  for (size_t c = 0; c < 4; ++c) out[c] = float(rotations[(k * count + i) * 4 + c]) / 127.0f;
  return out;
}

std::array<float, 3> ViewPayload::LogScale(size_t k, size_t i) const {
  k = std::min(k, size_t(scale_frames - 1));
  std::array<float, 3> out;
  for (size_t c = 0; c < 3; ++c) out[c] = splatv::HalfToFloat(log_scales[(k * count + i) * 3 + c]);
  return out;
}

std::array<float, 4> ViewPayload::ColourOpacity(size_t k, size_t i) const {
  k = std::min(k, size_t(colour_frames - 1));
  std::array<float, 4> out;
  const uint8_t* v = &colours[(k * count + i) * 4];
  for (size_t c = 0; c < 3; ++c) out[c] = colour_range[0] + v[c] / 255.0f * (colour_range[1] - colour_range[0]);
  out[3] = v[3] / 255.0f * opacity_scale;
  return out;
}

}  // namespace atex
