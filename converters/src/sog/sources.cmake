# Converter 'sog': PlayCanvas SOG v2 (meta.json + WebP images, as a folder or a .sog
# zip). WebP decoding needs libwebp (optional: without it SOG input is refused).
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/sog_read.cc)
