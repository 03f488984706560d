#include "proto/scene/import/gltf/file_access.h"

#include <cctype>
#include <fstream>
#include <iterator>
#include <limits>
#include <string_view>
#include <system_error>

#include "proto/scene/import/gltf_data_uris.h"
#include "proto/scene/import/scene_files.h"
#include "proto/scene/scene.h"

namespace tcfarm::gltf {

namespace {

bool IsEscapeAt(const std::string& text, size_t i) {
  return text[i] == '%' && i + 2 < text.size() && std::isxdigit(static_cast<unsigned char>(text[i + 1])) &&
         std::isxdigit(static_cast<unsigned char>(text[i + 2]));
}

}  // namespace

bool HasMalformedEscape(const std::string& text) {
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '%' && !IsEscapeAt(text, i)) return true;
  }
  return false;
}

std::string UrlDecode(const std::string& text) {
  std::string decoded;
  for (size_t i = 0; i < text.size(); ++i) {
    if (IsEscapeAt(text, i)) {
      decoded += static_cast<char>(std::stoi(text.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      decoded += text[i];
    }
  }
  return decoded;
}

namespace {

// tinygltf joins a uri to the folder, or to "." (or to nothing, without a folder).
std::optional<size_t> EmbeddedIndexOf(const FileAccess& access, std::string_view path) {
  for (std::string_view base : {std::string_view(access.prefix), std::string_view("./")}) {
    if (!base.empty() && path.substr(0, base.size()) == base) path.remove_prefix(base.size());
  }
  const std::optional<size_t> index = gltf::EmbeddedIndex(path);
  if (!index || *index >= access.embedded->size()) return std::nullopt;
  return index;
}

bool Inside(const FileAccess& access, const std::string& path, std::filesystem::path* resolved) {
  if (!access.folder || path.compare(0, access.prefix.size(), access.prefix) != 0) return false;
  try {
    *resolved = ResolveInsideFolder(*access.folder, path.substr(access.prefix.size()), "", "file");
  } catch (const SceneError&) {
    return false;
  }
  std::error_code error;
  return std::filesystem::is_regular_file(*resolved, error);
}

}  // namespace

bool FileExistsInside(const std::string& path, void* user) {
  const FileAccess& access = *static_cast<FileAccess*>(user);
  std::filesystem::path resolved;
  return EmbeddedIndexOf(access, path) || Inside(access, path, &resolved);
}

std::string ExpandNothing(const std::string& path, void*) { return path; }

bool ReadFileInside(std::vector<unsigned char>* out, std::string* error, const std::string& path, void* user) {
  const FileAccess& access = *static_cast<FileAccess*>(user);
  if (const std::optional<size_t> index = EmbeddedIndexOf(access, path)) {
    out->swap((*access.embedded)[*index]);  // tinygltf swaps it on into the buffer or image: no copy
    return true;
  }
  std::filesystem::path resolved;
  if (!Inside(access, path, &resolved)) {
    if (error) *error = "not a readable file inside the scene folder";
    return false;
  }
  std::ifstream in(resolved, std::ios::binary);
  out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (in.bad()) {
    if (error) *error = "read error";
    return false;
  }
  return true;
}

bool WriteNothing(std::string* error, const std::string&, const std::vector<unsigned char>&, void*) {
  if (error) *error = "the importer writes no files";
  return false;
}

// tinygltf 2.7 hands an image stored in a bufferView to the image loader without checking
// that the view lies inside its buffer: a GLB whose view runs past the binary chunk would

namespace {

// that the view lies inside its buffer: a GLB whose view runs past the binary chunk would
// be read out of bounds. The model being loaded already holds its views and buffers.
std::string ImageViewOutsideBuffer(const tinygltf::Model& model, const tinygltf::Image& image, int imageIndex) {
  if (image.bufferView < 0) return "";  // a data: URI or a file, decoded into memory tinygltf owns
  const tinygltf::BufferView& view = model.bufferViews.at(static_cast<size_t>(image.bufferView));
  const tinygltf::Buffer& buffer = model.buffers.at(static_cast<size_t>(view.buffer));
  const size_t size = buffer.data.size();
  if (view.byteOffset <= size && view.byteLength <= size - view.byteOffset &&
      view.byteLength <= static_cast<size_t>(std::numeric_limits<int>::max())) {
    return "";
  }
  return "image " + std::to_string(imageIndex) + "'s bufferView " + std::to_string(image.bufferView) +
         " (bytes " + std::to_string(view.byteOffset) + " + " + std::to_string(view.byteLength) +
         ") runs past the end of buffer " + std::to_string(view.buffer) + " (" + std::to_string(size) + " bytes)";
}

}  // namespace

// built, and the bytes' hash names the image wherever the scene travels.
bool KeepImageEncoded(tinygltf::Image* image, const int imageIndex, std::string* error, std::string*, int, int,
                      const unsigned char* bytes, int size, void* loadingModel) {
  const std::string outside =
      ImageViewOutsideBuffer(*static_cast<const tinygltf::Model*>(loadingModel), *image, imageIndex);
  if (!outside.empty() || size < 0) {
    if (error) *error += outside.empty() ? "image " + std::to_string(imageIndex) + " is too large" : outside;
    return false;
  }
  image->image.assign(bytes, bytes + size);
  image->as_is = true;
  return true;
}

}  // namespace tcfarm::gltf
