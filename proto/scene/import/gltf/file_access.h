// tinygltf's file and image callbacks: external files only from inside the scene's folder,
// data URIs decoded beforehand (gltf_data_uris.h), images kept encoded.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <tiny_gltf.h>

namespace tcfarm::gltf {

// tinygltf reads external files only through these, so that a file never reaches outside
// the scene's folder and data without a folder never reads any. They also hand over the
// file's data URIs, decoded beforehand (gltf_data_uris.h), under the names that replaced them.
struct FileAccess {
  std::optional<std::filesystem::path> folder;
  std::string prefix;  // folder as tinygltf joins it, with a trailing '/'
  std::vector<std::vector<unsigned char>>* embedded;
};

bool FileExistsInside(const std::string& path, void* user);
std::string ExpandNothing(const std::string& path, void*);
bool ReadFileInside(std::vector<unsigned char>* out, std::string* error, const std::string& path, void* user);
bool WriteNothing(std::string* error, const std::string&, const std::vector<unsigned char>&, void*);
// Images are kept as their file's bytes (PNG, JPEG, WebP): workers decode them when a scene is
// built, and the bytes' hash names the image wherever the scene travels.
bool KeepImageEncoded(tinygltf::Image* image, int imageIndex, std::string* error, std::string*, int, int,
                      const unsigned char* bytes, int size, void* loadingModel);

// A uri's %XX escapes decoded.
std::string UrlDecode(const std::string& text);
// True when a '%' in `text` is not followed by two hex digits: tinygltf's own decoding then
// names another file than UrlDecode, so such a uri is refused rather than half-read.
bool HasMalformedEscape(const std::string& text);

}  // namespace tcfarm::gltf
