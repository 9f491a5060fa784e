// Format dispatch by extension lives in converters/src/convert/convert.cc
// (atex/converters/convert.h); this file keeps a stable anchor symbol.
namespace atex::converters {
int RegistryAnchor() { return 0; }
}  // namespace atex::converters
