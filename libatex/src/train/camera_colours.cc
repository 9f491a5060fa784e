#include "atex/train/camera_colours.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace atex::train {

const ColourAffine& CameraColours::For(int camera_id) const {
  static const ColourAffine kIdentity;
  auto it = by_camera_.find(camera_id);
  return it == by_camera_.end() ? kIdentity : it->second;
}

Status CameraColours::Fit(const Dataset& dataset, Backend& backend, const RenderRequest& request,
                          const CameraColourConfig& config) {
  if (config.views_per_camera < 1) {
    return MakeError(StatusCode::kInvalidArgument, "camera_colour.views_per_camera ", config.views_per_camera,
                     " must be >= 1");
  }
  std::map<int, std::vector<const View*>> frames;
  for (const View& v : dataset.train_views()) {
    if (v.camera_id >= 0) frames[v.camera_id].push_back(&v);
  }
  std::vector<int> cameras;
  std::vector<ColourAffine> fitted;
  for (auto& [camera, views] : frames) {
    // A camera seen once (D-NeRF's moving camera: one per frame) is no rig camera with a colour
    // response of its own: an affine of a single frame would also absorb the frame's content.
    if (views.size() < 2) continue;
    std::sort(views.begin(), views.end(), [](const View* a, const View* b) { return a->camera.time < b->camera.time; });
    const size_t want = std::min(views.size(), static_cast<size_t>(config.views_per_camera));
    std::vector<Image> renders(want);
    std::vector<std::shared_ptr<const Image>> targets(want);
    std::vector<ImagePair> pairs;
    for (size_t i = 0; i < want; ++i) {
      // Evenly spaced over the camera's frames, the first and the last included.
      const size_t index = want == 1 ? views.size() / 2 : i * (views.size() - 1) / (want - 1);
      ATEX_ASSIGN_OR_RETURN(renders[i], backend.Render(views[index]->camera, request));
      ATEX_ASSIGN_OR_RETURN(targets[i], dataset.LoadImage(*views[index]));
      pairs.push_back({&renders[i], targets[i].get()});
    }
    StatusOr<ColourAffine> affine = FitColourAffine(pairs, config.keep);
    if (!affine.ok()) return MakeError(affine.status().code(), "camera ", camera, ": ", affine.status().message());
    cameras.push_back(camera);
    fitted.push_back(*affine);
  }
  NormaliseColourAffines(&fitted);
  by_camera_.clear();
  for (size_t i = 0; i < cameras.size(); ++i) by_camera_[cameras[i]] = fitted[i];
  return Status::Ok();
}

nlohmann::json CameraColours::ToJson() const {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [camera, a] : by_camera_) j[std::to_string(camera)] = {{"gain", a.gain}, {"offset", a.offset}};
  return j;
}

StatusOr<CameraColours> CameraColours::FromJson(const nlohmann::json& json) {
  if (!json.is_object()) return MakeError(StatusCode::kInvalidArgument, "camera colours: not a JSON object");
  CameraColours out;
  for (auto it = json.begin(); it != json.end(); ++it) {
    int camera = -1;
    if (std::sscanf(it.key().c_str(), "%d", &camera) != 1 || camera < 0 || std::to_string(camera) != it.key()) {
      return MakeError(StatusCode::kInvalidArgument, "camera colours: key '", it.key(), "' is not a camera id");
    }
    ColourAffine a;
    const nlohmann::json& e = it.value();
    const bool shaped = e.is_object() && e.contains("gain") && e.contains("offset") && e["gain"].is_array() &&
                        e["offset"].is_array() && e["gain"].size() == 3 && e["offset"].size() == 3;
    if (!shaped) return MakeError(StatusCode::kInvalidArgument, "camera colours: camera ", camera, " is malformed");
    for (int c = 0; c < 3; ++c) {
      if (!e["gain"][c].is_number() || !e["offset"][c].is_number()) {
        return MakeError(StatusCode::kInvalidArgument, "camera colours: camera ", camera, " has a non-number");
      }
      a.gain[c] = e["gain"][c].get<float>();
      a.offset[c] = e["offset"][c].get<float>();
      if (!(a.gain[c] >= kMinColourGain && a.gain[c] <= kMaxColourGain) ||
          !(std::abs(a.offset[c]) <= kMaxColourOffset)) {
        return MakeError(StatusCode::kInvalidArgument, "camera colours: camera ", camera, " channel ", c, " gain ",
                         a.gain[c], " or offset ", a.offset[c], " is outside [", kMinColourGain, ", ",
                         kMaxColourGain, "] / ±", kMaxColourOffset);
      }
    }
    out.by_camera_[camera] = a;
  }
  return out;
}

std::string CameraColours::Summary() const {
  if (by_camera_.empty()) return "no cameras";
  std::string s = std::to_string(by_camera_.size()) + " cameras";
  const char* names = "RGB";
  char buf[96];
  for (int c = 0; c < 3; ++c) {
    float glo = 1e9f, ghi = -1e9f, olo = 1e9f, ohi = -1e9f;
    for (const auto& [camera, a] : by_camera_) {
      glo = std::min(glo, a.gain[c]), ghi = std::max(ghi, a.gain[c]);
      olo = std::min(olo, a.offset[c]), ohi = std::max(ohi, a.offset[c]);
    }
    std::snprintf(buf, sizeof buf, ", %c gain %.3f..%.3f offset %+.3f..%+.3f", names[c], glo, ghi, olo, ohi);
    s += buf;
  }
  return s;
}

}  // namespace atex::train
