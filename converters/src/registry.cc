// Intentionally small: format dispatch by extension lives in converters/src/dispatch
// once formats exist. This file keeps the library non-empty.
namespace atex::converters {
int RegistryAnchor() { return 0; }
}  // namespace atex::converters
