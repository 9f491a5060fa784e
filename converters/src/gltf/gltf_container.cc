#include "gltf/gltf_container.h"

#include <algorithm>
#include <cstring>
#include <string_view>

#include "gltf/gltf_names.h"
#include "gltf/gltf_writer.h"
#include "gltf/meshopt_codec.h"

#ifdef ATEX_HAVE_MESHOPT
#include <meshoptimizer.h>
#endif

namespace atex::gltf {
namespace {

using nlohmann::json;

constexpr uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr uint32_t kGlbChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kGlbChunkBin = 0x004E4942;   // "BIN\0"
constexpr int kMaxJsonDepth = 64;               // tinygltf converts extension JSON recursively
// A meshopt attribute stream spends at least 2 bits per 16 bytes of output (one group
// header per 16 elements of each byte lane), so a view expands at most 64x; files that
// claim more are forged. The same bound caps the total expansion of a file.
constexpr uint64_t kMeshoptMaxExpansion = 64;

uint32_t U32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}
void PutU32(std::vector<uint8_t>& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i)));
}
size_t Align4(size_t n) { return (n + 3) & ~size_t{3}; }

struct Container {
  std::string_view json;
  const uint8_t* bin = nullptr;
  size_t bin_size = 0;
  bool glb = false;
};

StatusOr<Container> SplitContainer(const uint8_t* data, size_t size) {
  Container c;
  if (size >= 4 && U32(data) == kGlbMagic) {
    c.glb = true;
    if (size < 12) return MakeError(StatusCode::kTruncated, "GLB header needs 12 bytes, the file has ", size);
    const uint32_t version = U32(data + 4);
    if (version != 2) return MakeError(StatusCode::kUnsupportedVersion, "GLB version ", version, " (only 2 is known)");
    const uint64_t length = U32(data + 8);
    if (length > size)
      return MakeError(StatusCode::kTruncated, "GLB header says ", length, " bytes, the file has ", size);
    if (length < 20)
      return MakeError(StatusCode::kCorrupt, "GLB length ", length, " leaves no room for the JSON chunk");
    uint64_t offset = 12;
    bool first = true;
    while (offset + 8 <= length) {
      const uint64_t chunk_length = U32(data + offset);
      const uint32_t chunk_type = U32(data + offset + 4);
      if (chunk_length > length - offset - 8) {
        return MakeError(StatusCode::kTruncated, "GLB chunk at byte ", offset, " claims ", chunk_length,
                         " bytes; only ", length - offset - 8, " remain");
      }
      const uint8_t* payload = data + offset + 8;
      if (first) {
        if (chunk_type != kGlbChunkJson) return MakeError(StatusCode::kCorrupt, "GLB chunk 0 at byte 12 is not JSON");
        c.json = std::string_view(reinterpret_cast<const char*>(payload), chunk_length);
        first = false;
      } else if (chunk_type == kGlbChunkBin && c.bin == nullptr) {
        c.bin = payload;
        c.bin_size = chunk_length;
      }  // other chunk types are ignored (glTF 2.0, "GLB file format")
      offset += 8 + chunk_length;
    }
    if (first) return MakeError(StatusCode::kTruncated, "GLB has no JSON chunk");
    return c;
  }
  size_t start = 0;
  if (size >= 3 && data[0] == 0xEF && data[1] == 0xBB && data[2] == 0xBF) start = 3;  // tolerate a UTF-8 BOM
  while (start < size && (data[start] == ' ' || data[start] == '\n' || data[start] == '\r' || data[start] == '\t'))
    ++start;
  if (start >= size || data[start] != '{') return MakeError(StatusCode::kBadMagic, "neither GLB nor glTF JSON");
  c.json = std::string_view(reinterpret_cast<const char*>(data), size);
  return c;
}

StatusOr<std::vector<uint8_t>> Base64Decode(std::string_view text, const std::string& where) {
  auto value = [](char ch) -> int {
    if (ch >= 'A' && ch <= 'Z') return ch - 'A';
    if (ch >= 'a' && ch <= 'z') return ch - 'a' + 26;
    if (ch >= '0' && ch <= '9') return ch - '0' + 52;
    if (ch == '+') return 62;
    if (ch == '/') return 63;
    return -1;
  };
  while (!text.empty() && text.back() == '=') text.remove_suffix(1);
  std::vector<uint8_t> out;
  out.reserve(text.size() / 4 * 3 + 3);
  uint32_t acc = 0;
  int bits = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const int v = value(text[i]);
    if (v < 0) return MakeError(StatusCode::kCorrupt, where, ": invalid base64 character at offset ", i);
    acc = (acc << 6) | uint32_t(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(uint8_t(acc >> bits));
    }
  }
  return out;
}

// Largest nesting depth of a JSON value, iteratively (hostile input may be deep).
int JsonDepth(const json& root) {
  int max_depth = 0;
  std::vector<std::pair<const json*, int>> stack{{&root, 1}};
  while (!stack.empty()) {
    auto [value, depth] = stack.back();
    stack.pop_back();
    max_depth = std::max(max_depth, depth);
    if (depth > kMaxJsonDepth) break;
    if (value->is_structured()) {
      for (const auto& child : *value) stack.push_back({&child, depth + 1});
    }
  }
  return max_depth;
}

Status ReadSize(const json& object, const char* key, bool required, uint64_t default_value, const std::string& where,
                uint64_t* out) {
  auto it = object.find(key);
  if (it == object.end()) {
    if (required) return MakeError(StatusCode::kCorrupt, where, ": missing '", key, "'");
    *out = default_value;
    return Status::Ok();
  }
  if (!it->is_number_integer() || (it->is_number_integer() && !it->is_number_unsigned() && it->get<int64_t>() < 0)) {
    return MakeError(StatusCode::kCorrupt, where, ".", key, " is not a non-negative integer");
  }
  *out = it->get<uint64_t>();
  if (*out > (uint64_t{1} << 53))
    return MakeError(StatusCode::kLimitExceeded, where, ".", key, " = ", *out, " is too large");
  return Status::Ok();
}

struct BufferSource {
  const uint8_t* data = nullptr;  // null for a meshopt fallback buffer
  uint64_t length = 0;            // byteLength
  uint64_t base = 0;              // where its bytes start in the normalized buffer
};

Status DecodeMeshoptView(const json& ext, const std::vector<BufferSource>& buffers, const std::string& where,
                         uint64_t parent_length, uint64_t budget_left, std::vector<uint8_t>& out, uint64_t* start) {
  if (!ext.is_object()) return MakeError(StatusCode::kCorrupt, where, " is not an object");
  uint64_t buffer = 0, offset = 0, length = 0, stride = 0, count = 0;
  ATEX_RETURN_IF_ERROR(ReadSize(ext, "buffer", true, 0, where, &buffer));
  ATEX_RETURN_IF_ERROR(ReadSize(ext, "byteOffset", false, 0, where, &offset));
  ATEX_RETURN_IF_ERROR(ReadSize(ext, "byteLength", true, 0, where, &length));
  ATEX_RETURN_IF_ERROR(ReadSize(ext, "byteStride", true, 0, where, &stride));
  ATEX_RETURN_IF_ERROR(ReadSize(ext, "count", true, 0, where, &count));
  if (buffer >= buffers.size() || buffers[buffer].data == nullptr) {
    return MakeError(StatusCode::kCorrupt, where, ".buffer ", buffer, " is not a buffer with data");
  }
  if (offset > buffers[buffer].length || length > buffers[buffer].length - offset) {
    return MakeError(StatusCode::kCorrupt, where, ": bytes ", offset, "+", length, " exceed buffer ", buffer, " (",
                     buffers[buffer].length, " bytes)");
  }
  auto mode_it = ext.find("mode");
  if (mode_it == ext.end() || !mode_it->is_string()) return MakeError(StatusCode::kCorrupt, where, ".mode is missing");
  const std::string mode = mode_it->get<std::string>();
  MeshoptFilter filter = MeshoptFilter::kNone;
  if (auto f = ext.find("filter"); f != ext.end()) {
    if (!f->is_string()) return MakeError(StatusCode::kCorrupt, where, ".filter is not a string");
    ATEX_ASSIGN_OR_RETURN(filter, ParseMeshoptFilter(f->get<std::string>()));
  }
  if (stride == 0 || stride > 256 || count == 0)
    return MakeError(StatusCode::kCorrupt, where, ": byteStride ", stride, " count ", count);
  const uint64_t decoded = count * stride;  // both < 2^53 / 256: no overflow
  if (count > (uint64_t{1} << 40) || decoded != parent_length) {
    return MakeError(StatusCode::kCorrupt, where, ": count*byteStride = ", count, "*", stride,
                     " differs from the view's byteLength ", parent_length);
  }
  if (decoded > kMeshoptMaxExpansion * length + 4096) {
    return MakeError(StatusCode::kCorrupt, where, ": ", length, " compressed bytes cannot hold ", decoded, " bytes");
  }
  if (decoded > budget_left)
    return MakeError(StatusCode::kLimitExceeded, where, ": decoding would exceed the size limit");
  if (!MeshoptAvailable()) {
    return MakeError(StatusCode::kUnsupported, "EXT_meshopt_compression needs meshoptimizer, which this build lacks");
  }
  out.resize(Align4(out.size()));
  *start = out.size();
  out.resize(out.size() + decoded);
  uint8_t* target = out.data() + *start;
  const uint8_t* stream = buffers[buffer].data + offset;
  if (mode == "ATTRIBUTES") {
    if (stride % 4 != 0)
      return MakeError(StatusCode::kCorrupt, where, ": ATTRIBUTES byteStride ", stride, " is not a multiple of 4");
    Status s = DecompressAttributes(stream, length, count, stride, target);
    if (!s.ok()) return s.WithContext(where);
    s = DecodeFilter(filter, target, count, stride);
    if (!s.ok()) return s.WithContext(where);
    return Status::Ok();
  }
#ifdef ATEX_HAVE_MESHOPT
  if (mode == "TRIANGLES" || mode == "INDICES") {
    if (stride != 2 && stride != 4) return MakeError(StatusCode::kCorrupt, where, ": index byteStride ", stride);
    if (filter != MeshoptFilter::kNone) return MakeError(StatusCode::kCorrupt, where, ": index streams take no filter");
    if (mode == "TRIANGLES" && count % 3 != 0)
      return MakeError(StatusCode::kCorrupt, where, ": TRIANGLES count ", count, " % 3 != 0");
    const int rc = mode == "TRIANGLES" ? meshopt_decodeIndexBuffer(target, count, stride, stream, length)
                                       : meshopt_decodeIndexSequence(target, count, stride, stream, length);
    if (rc != 0) return MakeError(StatusCode::kCorrupt, where, ": index stream does not decode (code ", rc, ")");
    return Status::Ok();
  }
#endif
  return MakeError(StatusCode::kCorrupt, where, ".mode '", mode, "' is not ATTRIBUTES, TRIANGLES or INDICES");
}

void RemoveFromList(json& doc, const char* key, const char* name) {
  auto it = doc.find(key);
  if (it == doc.end() || !it->is_array()) return;
  json kept = json::array();
  for (const auto& e : *it) {
    if (!(e.is_string() && e.get<std::string>() == name)) kept.push_back(e);
  }
  if (kept.empty()) {
    doc.erase(key);
  } else {
    *it = kept;
  }
}

// The document of the container, refused when it is no JSON object or nests too deep.
StatusOr<json> ParseDocument(const Container& container) {
  json doc = json::parse(container.json.begin(), container.json.end(), nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return MakeError(StatusCode::kCorrupt, "glTF JSON does not parse");
  if (!doc.is_object()) return MakeError(StatusCode::kCorrupt, "glTF JSON is not an object");
  if (JsonDepth(doc) > kMaxJsonDepth) {
    return MakeError(StatusCode::kLimitExceeded, "glTF JSON nests deeper than ", kMaxJsonDepth, " levels");
  }
  return doc;
}

// The bytes of a buffer's uri: a base64 data: URI, or an external file through `loader` (whose
// size is added to *input_bytes, the bound of the meshopt expansion).
StatusOr<std::vector<uint8_t>> LoadBufferUri(const std::string& text, const std::string& where, const UriLoader& loader,
                                             const GltfImportOptions& options, uint64_t* input_bytes) {
  if (text.rfind("data:", 0) == 0) {
    const size_t comma = text.find(',');
    if (comma == std::string::npos || text.substr(0, comma).find(";base64") == std::string::npos) {
      return MakeError(StatusCode::kUnsupported, where, ": only base64 data: URIs are supported");
    }
    return Base64Decode(std::string_view(text).substr(comma + 1), where);
  }
  if (!loader)
    return MakeError(StatusCode::kUnsupported, where, " refers to external file '", text,
                     "'; read the file from disk instead");
  ATEX_ASSIGN_OR_RETURN(std::string path, PercentDecode(text));
  auto bytes = loader(path, options.max_decoded_bytes);
  if (!bytes.ok()) return bytes.status().WithContext(where);
  *input_bytes += bytes->size();
  return bytes;
}

// The buffers and where each one's bytes are: its uri (the bytes kept in *owned), the GLB binary
// chunk (buffer 0 of a GLB), or none for a meshopt fallback buffer.
StatusOr<std::vector<BufferSource>> ResolveBuffers(const json& doc, const Container& container, const UriLoader& loader,
                                                   const GltfImportOptions& options,
                                                   std::vector<std::vector<uint8_t>>* owned, uint64_t* input_bytes) {
  std::vector<BufferSource> buffers;
  auto it = doc.find("buffers");
  if (it == doc.end()) return buffers;
  if (!it->is_array()) return MakeError(StatusCode::kCorrupt, "'buffers' is not an array");
  owned->reserve(it->size());
  for (size_t i = 0; i < it->size(); ++i) {
    const json& b = (*it)[i];
    const std::string where = StrCat("buffers[", i, "]");
    if (!b.is_object()) return MakeError(StatusCode::kCorrupt, where, " is not an object");
    BufferSource source;
    ATEX_RETURN_IF_ERROR(ReadSize(b, "byteLength", true, 0, where, &source.length));
    auto uri = b.find("uri");
    if (uri != b.end()) {
      if (!uri->is_string()) return MakeError(StatusCode::kCorrupt, where, ".uri is not a string");
      ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes,
                            LoadBufferUri(uri->get_ref<const std::string&>(), where, loader, options, input_bytes));
      owned->push_back(std::move(bytes));
      if (owned->back().size() < source.length) {
        return MakeError(StatusCode::kTruncated, where, " has ", owned->back().size(), " bytes, byteLength says ",
                         source.length);
      }
      source.data = owned->back().data();
    } else if (container.glb && i == 0 && container.bin != nullptr) {
      if (source.length > container.bin_size) {
        return MakeError(StatusCode::kTruncated, where, ".byteLength ", source.length,
                         " exceeds the GLB binary chunk (", container.bin_size, " bytes)");
      }
      source.data = container.bin;
    } else {
      const json* ext = nullptr;
      if (auto e = b.find("extensions"); e != b.end() && e->is_object()) {
        if (auto m = e->find(kExtMeshopt); m != e->end()) ext = &*m;
      }
      if (ext == nullptr || !ext->is_object() || ext->value("fallback", false) != true) {
        return MakeError(StatusCode::kCorrupt, where,
                         " has no uri and is neither the GLB binary chunk nor a meshopt fallback");
      }
    }
    buffers.push_back(source);
  }
  return buffers;
}

// The start of the normalized buffer: every buffer with data, each 4-byte aligned; sets their
// `base`.
StatusOr<std::vector<uint8_t>> ConcatenateBuffers(std::vector<BufferSource>& buffers,
                                                  const GltfImportOptions& options) {
  std::vector<uint8_t> bin;
  uint64_t plain_total = 0;
  for (const auto& b : buffers) plain_total += b.data ? Align4(b.length) : 0;
  if (plain_total > options.max_decoded_bytes)
    return MakeError(StatusCode::kLimitExceeded, "glTF buffers hold ", plain_total, " bytes");
  bin.reserve(plain_total);
  for (auto& b : buffers) {
    if (b.data == nullptr) continue;
    bin.resize(Align4(bin.size()));
    b.base = bin.size();
    bin.insert(bin.end(), b.data, b.data + b.length);
  }
  return bin;
}

// Points every buffer view at the normalized buffer `bin`: a plain view at its buffer's copy, a
// meshopt view at its decoded bytes, appended to `bin` (*decoded_total counts them against
// `expansion_limit`; *had_meshopt is set).
Status RewriteBufferViews(json& doc, const std::vector<BufferSource>& buffers, uint64_t expansion_limit,
                          std::vector<uint8_t>& bin, bool* had_meshopt) {
  uint64_t decoded_total = 0;
  auto it = doc.find("bufferViews");
  if (it == doc.end()) return Status::Ok();
  if (!it->is_array()) return MakeError(StatusCode::kCorrupt, "'bufferViews' is not an array");
  for (size_t i = 0; i < it->size(); ++i) {
    json& view = (*it)[i];
    const std::string where = StrCat("bufferViews[", i, "]");
    if (!view.is_object()) return MakeError(StatusCode::kCorrupt, where, " is not an object");
    uint64_t length = 0;
    ATEX_RETURN_IF_ERROR(ReadSize(view, "byteLength", true, 0, where, &length));
    json* ext = nullptr;
    auto exts = view.find("extensions");
    if (exts != view.end() && exts->is_object()) {
      if (auto m = exts->find(kExtMeshopt); m != exts->end()) ext = &*m;
    }
    if (ext != nullptr) {
      uint64_t start = 0;
      ATEX_RETURN_IF_ERROR(DecodeMeshoptView(*ext, buffers, where + ".extensions.EXT_meshopt_compression", length,
                                             expansion_limit - decoded_total, bin, &start));
      decoded_total += length;
      exts->erase(kExtMeshopt);
      if (exts->empty()) view.erase("extensions");
      view["buffer"] = 0;
      view["byteOffset"] = start;
      *had_meshopt = true;
      continue;
    }
    uint64_t buffer = 0, offset = 0;
    ATEX_RETURN_IF_ERROR(ReadSize(view, "buffer", true, 0, where, &buffer));
    ATEX_RETURN_IF_ERROR(ReadSize(view, "byteOffset", false, 0, where, &offset));
    if (buffer >= buffers.size()) return MakeError(StatusCode::kCorrupt, where, ".buffer ", buffer, " does not exist");
    if (buffers[buffer].data == nullptr) {
      return MakeError(StatusCode::kCorrupt, where, " reads fallback buffer ", buffer, ", which holds no data");
    }
    if (offset > buffers[buffer].length || length > buffers[buffer].length - offset) {
      return MakeError(StatusCode::kCorrupt, where, ": bytes ", offset, "+", length, " exceed buffer ", buffer, " (",
                       buffers[buffer].length, " bytes)");
    }
    view["buffer"] = 0;
    view["byteOffset"] = buffers[buffer].base + offset;
  }
  return Status::Ok();
}

// A GLB of the document and the (4-byte aligned) binary chunk `bin`, empty for none.
StatusOr<std::vector<uint8_t>> AssembleGlb(const json& doc, const std::vector<uint8_t>& bin) {
  std::string text = DumpJson(doc);
  text.resize(Align4(text.size()), ' ');
  const uint64_t total = 12 + 8 + text.size() + (bin.empty() ? 0 : 8 + bin.size());
  if (total > UINT32_MAX)
    return MakeError(StatusCode::kLimitExceeded, "glTF of ", total, " bytes exceeds the 4 GiB GLB limit of the parser");
  std::vector<uint8_t> glb;
  glb.reserve(total);
  PutU32(glb, kGlbMagic);
  PutU32(glb, 2);
  PutU32(glb, uint32_t(total));
  PutU32(glb, uint32_t(text.size()));
  PutU32(glb, kGlbChunkJson);
  glb.insert(glb.end(), text.begin(), text.end());
  if (!bin.empty()) {
    PutU32(glb, uint32_t(bin.size()));
    PutU32(glb, kGlbChunkBin);
    glb.insert(glb.end(), bin.begin(), bin.end());
  }
  return glb;
}

}  // namespace

StatusOr<std::string> PercentDecode(const std::string& uri) {
  std::string out;
  for (size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] != '%') {
      out.push_back(uri[i]);
      continue;
    }
    auto hex = [](char c) -> int {
      if (c >= '0' && c <= '9') return c - '0';
      if (c >= 'a' && c <= 'f') return c - 'a' + 10;
      if (c >= 'A' && c <= 'F') return c - 'A' + 10;
      return -1;
    };
    if (i + 2 >= uri.size() || hex(uri[i + 1]) < 0 || hex(uri[i + 2]) < 0) {
      return MakeError(StatusCode::kCorrupt, "malformed percent escape in URI '", uri, "'");
    }
    out.push_back(char(hex(uri[i + 1]) * 16 + hex(uri[i + 2])));
    i += 2;
  }
  return out;
}

std::string PercentEncode(const std::string& text) {
  static const char* kHex = "0123456789ABCDEF";
  std::string out;
  for (unsigned char c : text) {
    if ((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '_' ||
        c == '.' || c == '~' || c == '/') {
      out.push_back(char(c));
    } else {
      out.push_back('%');
      out.push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 15]);
    }
  }
  return out;
}

StatusOr<NormalizedGltf> NormalizeGltf(const uint8_t* data, size_t size, const UriLoader& loader,
                                       const GltfImportOptions& options) {
  ATEX_ASSIGN_OR_RETURN(Container container, SplitContainer(data, size));
  NormalizedGltf result;
  ATEX_ASSIGN_OR_RETURN(result.doc, ParseDocument(container));
  json& doc = result.doc;

  std::vector<std::vector<uint8_t>> owned;  // decoded data: URIs and external files
  uint64_t input_bytes = size;
  ATEX_ASSIGN_OR_RETURN(std::vector<BufferSource> buffers,
                        ResolveBuffers(doc, container, loader, options, &owned, &input_bytes));

  // The normalized buffer: every buffer with data, then every decoded meshopt view.
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bin, ConcatenateBuffers(buffers, options));
  const uint64_t expansion_limit =
      std::min<uint64_t>(options.max_decoded_bytes, kMeshoptMaxExpansion * input_bytes + (1u << 20));
  ATEX_RETURN_IF_ERROR(RewriteBufferViews(doc, buffers, expansion_limit, bin, &result.had_meshopt));
  // tinygltf would try to resolve image URIs; splat import never needs images.
  doc.erase("images");
  RemoveFromList(doc, "extensionsUsed", kExtMeshopt);
  RemoveFromList(doc, "extensionsRequired", kExtMeshopt);
  bin.resize(Align4(bin.size()));
  if (bin.empty()) {
    doc.erase("buffers");
  } else {
    doc["buffers"] = json::array({{{"byteLength", bin.size()}}});
  }
  ATEX_ASSIGN_OR_RETURN(result.glb, AssembleGlb(doc, bin));
  return result;
}

}  // namespace atex::gltf
