// Images held as their file's bytes (texture images: a PNG or JPEG uploaded, or a PNG, JPEG
// or WebP embedded in a glTF file), opened by OpenImageIO straight from memory.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

namespace tcfarm {

// The file name OpenImageIO should pick a reader by: bytes in memory have no extension,
// so their signature names the format ("image.png", "image.jpg", "image.webp"; "image" when unknown,
// and OpenImageIO then tries its readers in turn).
std::string ReaderNameFor(const std::string& bytes);

// An image being read from memory: the reader must outlive the input.
struct MemoryImageInput {
  std::unique_ptr<OIIO::Filesystem::IOMemReader> reader;
  std::unique_ptr<OIIO::ImageInput> input;  // null when no reader could open the bytes
  std::string error;                        // why, when input is null
};
MemoryImageInput OpenImageInMemory(const std::string& bytes);

// Why `bytes` are not an image every pixel of which decodes (the format is unknown, the
// header is broken, the pixel data ends early...), or nullopt when they are. Decodes the
// whole image a few rows at a time, so memory stays small whatever its size.
std::optional<std::string> EncodedImageProblem(const std::string& bytes);

// The most memory EncodedImageProblem may hold while it decodes `bytes`, known from the
// header alone: a reader may hold the whole image (WebP decodes it at once, a progressive
// JPEG keeps every coefficient), 2 bytes a channel, besides the rows it reads. 0 when no
// reader opens the bytes or they claim more texels than a texture may have (then
// EncodedImageProblem refuses them before decoding anything).
uint64_t EncodedImageDecodeBytes(const std::string& bytes);

}  // namespace tcfarm
