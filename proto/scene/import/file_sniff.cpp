#include "proto/scene/import/file_sniff.h"

#include <algorithm>
#include <cctype>
#include <cstdio>

#include "proto/scene/import/messages.h"

namespace tcfarm {
namespace {

constexpr std::string_view kByteOrderMark = "\xEF\xBB\xBF";
// How much of the start a message shows: enough to recognise, short enough for a line.
constexpr size_t kShownBytes = 16;
// How far into a text file an OBJ line is looked for (past a comment block at the top).
constexpr size_t kObjLinesLooked = 40;

struct Magic {
  std::string_view start;
  const char* what;
};

// Binary formats, known by their first bytes.
constexpr Magic kBinaryMagics[] = {
    {"PK\x03\x04", "a ZIP archive"},
    {"Kaydara FBX Binary", "an FBX file"},
    {"\x89PNG", "a PNG image"},
    {"\xFF\xD8\xFF", "a JPEG image"},
    {"%PDF", "a PDF document"},
    {"\x1F\x8B", "a gzip-compressed file"},
};

std::string_view WithoutTextStart(std::string_view bytes) {
  if (bytes.substr(0, kByteOrderMark.size()) == kByteOrderMark) bytes.remove_prefix(kByteOrderMark.size());
  const size_t first = bytes.find_first_not_of(" \t\r\n");
  return first == std::string_view::npos ? std::string_view() : bytes.substr(first);
}

bool StartsWithNoCase(std::string_view text, std::string_view prefix) {
  return text.size() >= prefix.size() &&
         std::equal(prefix.begin(), prefix.end(), text.begin(),
                    [](char lower, char c) { return std::tolower(static_cast<unsigned char>(c)) == lower; });
}

// The start as a message shows it: printable ASCII as it is, other bytes as \xNN.
std::string ShowStart(std::string_view bytes, size_t length) {
  std::string shown;
  for (unsigned char c : bytes.substr(0, length)) {
    if (c >= 0x20 && c < 0x7F && c != '"' && c != '\\') {
      shown += static_cast<char>(c);
    } else {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\x%02X", c);
      shown += escaped;
    }
  }
  return "\"" + shown + "\"";
}

std::string Seems(const char* what, std::string_view bytes, size_t length) {
  return std::string(what) + " (it starts with " + ShowStart(bytes, length) + ")";
}

bool IsText(std::string_view bytes) {
  return std::none_of(bytes.begin(), bytes.end(), [](char c) {
    const auto byte = static_cast<unsigned char>(c);
    return byte < 0x20 && byte != '\t' && byte != '\n' && byte != '\r';
  });
}

// An OBJ file's lines: vertices, comments, material libraries, objects, groups, faces.
bool IsObjLine(std::string_view line) {
  for (std::string_view keyword : {"v ", "vn ", "vt ", "f ", "o ", "g ", "mtllib ", "usemtl ", "#"}) {
    if (line.substr(0, keyword.size()) == keyword) return true;
  }
  return false;
}

// Text whose first lines are all OBJ lines (blank lines aside), at least one a vertex or an
// object: a comment alone says nothing about the format.
bool LooksLikeObj(std::string_view text) {
  bool geometry = false;
  size_t lines = 0;
  while (!text.empty() && lines < kObjLinesLooked) {
    const size_t end = text.find('\n');
    // The last line of a cut head may be cut inside its keyword: only a first line is judged whole.
    if (end == std::string_view::npos && lines > 0) break;
    std::string_view line = text.substr(0, end);
    text.remove_prefix(end == std::string_view::npos ? text.size() : end + 1);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.find_first_not_of(" \t") == std::string_view::npos) continue;
    if (!IsObjLine(line)) return false;
    geometry = geometry || line[0] != '#';
    ++lines;
  }
  return geometry;
}

void FailNotA(std::string_view bytes, const std::string& displayName, const std::string& format,
              const std::string& expected) {
  FailInput("", displayName + ": this is " + DescribeFileStart(bytes) + ", not " + format, expected);
}

}  // namespace

std::string DescribeFileStart(std::string_view bytes) {
  if (bytes.empty()) return "an empty file";
  for (const Magic& magic : kBinaryMagics) {
    if (bytes.substr(0, magic.start.size()) == magic.start) return Seems(magic.what, bytes, magic.start.size());
  }
  const std::string_view text = WithoutTextStart(bytes);
  if (text.empty()) return "a file of white space only";
  for (std::string_view html : {"<!doctype html", "<html"}) {
    if (StartsWithNoCase(text, html)) return Seems("an HTML page", text, html.size());
  }
  if (text.substr(0, 5) == "; FBX") return Seems("an FBX file", text, 5);
  if (bytes.substr(0, 4) == "glTF") return Seems("a binary glTF file", bytes, 4);
  if (StartsLikeJson(bytes)) return Seems("JSON text", text, 1);
  const std::string_view head = bytes.substr(0, 4096);
  if (!IsText(head)) return Seems("binary data", bytes, kShownBytes);
  if (LooksLikeObj(text.substr(0, 4096))) return Seems("an OBJ file", text, std::min(text.find('\n'), kShownBytes));
  return Seems("plain text that is not JSON", text, std::min(text.find('\n'), kShownBytes));
}

bool StartsLikeJson(std::string_view bytes) {
  const std::string_view text = WithoutTextStart(bytes);
  return !text.empty() && (text[0] == '{' || text[0] == '[');
}

void RequireGltfStart(std::string_view bytes, const std::string& displayName) {
  if (bytes.substr(0, 4) == "glTF" || StartsLikeJson(bytes)) return;
  FailNotA(bytes, displayName, "a glTF file", "a binary glTF (starts with \"glTF\") or glTF JSON");
}

void RequireJsonSceneStart(std::string_view bytes, const std::string& displayName) {
  if (StartsLikeJson(bytes)) return;
  FailNotA(bytes, displayName, "a tcfarm JSON scene", "a JSON object (proto/scene.md)");
}

}  // namespace tcfarm
