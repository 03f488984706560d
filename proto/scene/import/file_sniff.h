// What a file's first bytes say it is, for a scene file whose name promises a format its
// bytes are not: an HTML error page saved as shot.glb, a zipped download, an FBX or OBJ
// renamed. The importers ask here before their parsers run, so such a file is refused
// with what was expected and what it seems to be, not with a parser's complaint about
// byte 0.
#pragma once

#include <string>
#include <string_view>

namespace tcfarm {

// What the bytes seem to be, with the start that says so: "an HTML page (it starts with
// \"<!DOCTYPE html\")", "a ZIP archive (it starts with \"PK\\x03\\x04\")", "an empty file",
// "plain text that is not JSON (it starts with \"hello\")", "binary data (...)".
std::string DescribeFileStart(std::string_view bytes);

// JSON text at the top (after an optional UTF-8 byte order mark and white space): an
// object or an array. What kind of JSON it is, its parser says.
bool StartsLikeJson(std::string_view bytes);

// Throws SceneError "<name>: this is <what it seems>, not a glTF file; expected a binary
// glTF (starts with \"glTF\") or glTF JSON" unless the bytes start as GLB or JSON.
void RequireGltfStart(std::string_view bytes, const std::string& displayName);

// The same for a tcfarm JSON scene: JSON text, or refused saying what it seems to be.
void RequireJsonSceneStart(std::string_view bytes, const std::string& displayName);

}  // namespace tcfarm
