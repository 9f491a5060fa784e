// tinygltf's implementation, compiled from Debian's header as its README.Debian allows
// ("define TINYGLTF_IMPLEMENTATION in exactly one compilation unit").
//
// Why not Debian's libtinygltf.so: libdraco.so.7 (which libatex also links) exports its
// own bundled, older copy of tinygltf's symbols. Whichever library the dynamic linker
// searches first provides tinygltf::TinyGLTF::LoadBinaryFromMemory and friends; when it
// is Draco's, the caller's and the callee's struct layouts differ and the heap is
// corrupted (seen as "munmap_chunk(): invalid pointer" in `atex import`). Compiled
// here, every reference from atex_converters binds to this copy at static link time.
#ifdef ATEX_HAVE_TINYGLTF
#define TINYGLTF_IMPLEMENTATION
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wall"
#pragma GCC diagnostic ignored "-Wextra"
#endif
#include "gltf/tinygltf_config.h"
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif
#endif
