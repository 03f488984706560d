// The base64 data URIs of a glTF file's JSON ("uri" of buffers and images), decoded before
// tinygltf reads the JSON.
//
// tinygltf 2.7 would hold a data URI several times at once (its JSON document's string, a
// copy handed to its decoder, the buffer's `uri`, the decoded bytes grown one at a time in
// a string and then copied into the buffer): a 300 MiB URI cost over 3 GiB. Here each URI
// is decoded once, straight from the file's text into bytes of their exact size, and the
// text tinygltf parses names the bytes instead (EmbeddedName), which the importer's file
// callbacks then hand over without a copy. Decoded bytes are at most 3/4 of the URI's text,
// so never more than the file itself holds.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tcfarm::gltf {

struct EmbeddedData {
  std::string json;                               // the JSON with each data URI replaced by EmbeddedName(i)
  std::vector<std::vector<unsigned char>> bytes;  // URI i's bytes, decoded
};

// The name that stands for decoded URI `index` in the JSON tinygltf reads.
std::string EmbeddedName(size_t index);
// The index EmbeddedName gave `uri`, if it is one.
std::optional<size_t> EmbeddedIndex(std::string_view uri);

// The value of one base64 digit (RFC 4648: A-Z, a-z, 0-9, +, /), -1 for any other byte.
int Base64Value(unsigned char c);

// `json` with its base64 data URIs taken out and decoded. Throws SceneError naming
// `displayName` and the byte offset of a URI that is not base64, or of a "uri" that uses
// the reserved EmbeddedName form. JSON that does not parse is left for tinygltf to report.
EmbeddedData ExtractDataUris(std::string_view json, const std::string& displayName);

}  // namespace tcfarm::gltf
