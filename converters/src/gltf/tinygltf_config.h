// The one way our sources include tinygltf (Debian's libtinygltf-dev header), so that
// every translation unit sees the same configuration. Splat import never decodes or
// writes images and never opens files on its own (NormalizeGltf resolves buffers).
// Internal header.
#pragma once

#ifdef ATEX_HAVE_TINYGLTF
#ifndef TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE
#endif
#ifndef TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#endif
#ifndef TINYGLTF_NO_EXTERNAL_IMAGE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#endif
#include <tiny_gltf.h>
#endif
