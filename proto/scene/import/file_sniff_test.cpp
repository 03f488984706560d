#include "proto/scene/import/file_sniff.h"

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include "proto/scene/import/scene_import.h"
#include "proto/scene/scene.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

using namespace std::string_literals;

// The message a glTF import of these bytes refuses them with; empty when it does not say
// "not a glTF file" (it may fail later, in the parser, for another reason).
std::string GltfRefusal(const std::string& bytes) {
  try {
    ImportSceneBytes(bytes, "gltf");
  } catch (const SceneError& error) {
    const std::string what = error.what();
    if (what.find("not a glTF file") != std::string::npos) return what;
  }
  return "";
}

struct Foreign {
  const char* kind;
  std::string bytes;
  const char* seems;  // what the message must say the file is
};

const Foreign kForeignFiles[] = {
    {"html doctype", "<!DOCTYPE html>\n<html><body>Sign in</body></html>", "an HTML page (it starts with \"<!DOCTYPE html\")"},
    {"html tag", "\n  <html lang=\"en\"><head></head></html>", "an HTML page (it starts with \"<html\")"},
    {"zip", "PK\x03\x04\x14\x00\x00\x00"s, "a ZIP archive (it starts with \"PK\\x03\\x04\")"},
    {"fbx binary", "Kaydara FBX Binary  \x00\x1a\x00"s, "an FBX file (it starts with \"Kaydara FBX Binary\")"},
    {"fbx ascii", "; FBX 7.4.0 project file\n; ----\n", "an FBX file (it starts with \"; FBX\")"},
    {"obj", "# exported\nmtllib a.mtl\no cube\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "an OBJ file"},
    {"png", "\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR"s, "a PNG image (it starts with \"\\x89PNG\")"},
    {"jpeg", "\xFF\xD8\xFF\xE0\x00\x10JFIF"s, "a JPEG image (it starts with \"\\xFF\\xD8\\xFF\")"},
    {"pdf", "%PDF-1.7\n%\xE2\xE3\n", "a PDF document (it starts with \"%PDF\")"},
    {"empty", "", "an empty file"},
    {"gzip", "\x1F\x8B\x08\x00\x00\x00\x00\x00"s, "a gzip-compressed file (it starts with \"\\x1F\\x8B\")"},
    {"plain text", "hello, this is not a scene\nat all\n", "plain text that is not JSON (it starts with \"hello, this is n\")"},
    {"binary", "\x00\x01\x02\x03"s, "binary data (it starts with \"\\x00\\x01\\x02\\x03\")"},
};

TEST(FileSniffTest, EachForeignKindIsNamed) {
  for (const Foreign& file : kForeignFiles) {
    SCOPED_TRACE(file.kind);
    EXPECT_EQ(DescribeFileStart(file.bytes).rfind(file.seems, 0), 0u) << DescribeFileStart(file.bytes);
  }
}

TEST(FileSniffTest, EachForeignKindIsRefusedAsGltfSayingWhatItSeems) {
  for (const Foreign& file : kForeignFiles) {
    SCOPED_TRACE(file.kind);
    const std::string refusal = GltfRefusal(file.bytes);
    EXPECT_NE(refusal.find("this is "s + file.seems), std::string::npos) << refusal;
    EXPECT_NE(refusal.find("expected a binary glTF (starts with \"glTF\") or glTF JSON"), std::string::npos)
        << refusal;
  }
}

TEST(FileSniffTest, GlbAndJsonPassToTheirParsers) {
  EXPECT_TRUE(StartsLikeJson("\xEF\xBB\xBF  {\"asset\": {}}"));
  EXPECT_TRUE(StartsLikeJson("[1]"));
  EXPECT_FALSE(StartsLikeJson("asset"));
  EXPECT_NO_THROW(RequireGltfStart("glTF\x02\x00\x00\x00"s, "a.glb"));
  EXPECT_NO_THROW(RequireGltfStart("\n{\"asset\": {\"version\": \"2.0\"}}", "a.gltf"));
  // A broken GLB or JSON is the parser's to describe, with its byte or pointer.
  EXPECT_EQ(GltfRefusal("glTF\x01\x00\x00\x00"s), "");
  EXPECT_EQ(GltfRefusal("{\"asset\": "), "");
}

// An OBJ line needs geometry: a comment alone is text, and a line that is no OBJ keyword
// makes the whole file text.
TEST(FileSniffTest, ObjNeedsObjLinesOnly) {
  EXPECT_EQ(DescribeFileStart("# only a comment\n").rfind("plain text", 0), 0u);
  EXPECT_EQ(DescribeFileStart("v 0 0 0\nhello\n").rfind("plain text", 0), 0u);
  EXPECT_EQ(DescribeFileStart("\r\nv 0 0 0\r\nvn 0 0 1\r\n").rfind("an OBJ file", 0), 0u);
}

TEST(FileSniffTest, AFileNamedGlbSaysItsNameWhatItIsAndWhatWasExpected) {
  static std::atomic<int> counter{0};
  const fs::path folder = fs::temp_directory_path() / ("tcfarm_sniff_test_" + std::to_string(::getpid()) + "_" +
                                                       std::to_string(counter++));
  fs::create_directories(folder);
  std::ofstream(folder / "shot.glb", std::ios::binary) << "<!DOCTYPE html>\n<html></html>\n";
  std::string what;
  try {
    ImportScene(folder / "shot.glb");
  } catch (const SceneError& error) {
    what = error.what();
  }
  fs::remove_all(folder);
  EXPECT_EQ(what,
            "scene: shot.glb: this is an HTML page (it starts with \"<!DOCTYPE html\"), not a glTF file; expected a "
            "binary glTF (starts with \"glTF\") or glTF JSON");
}

TEST(FileSniffTest, AJsonSceneThatIsHtmlIsRefusedSayingSo) {
  std::string what;
  try {
    ImportSceneBytes("<html><body>502 Bad Gateway</body></html>", "tcfarm-json");
  } catch (const SceneError& error) {
    what = error.what();
  }
  EXPECT_NE(what.find("this is an HTML page (it starts with \"<html\"), not a tcfarm JSON scene"), std::string::npos)
      << what;
}

std::string AloneRefusal(const std::string& bytes, const std::string& name) {
  try {
    CheckSceneFileAlone(bytes, name);
  } catch (const SceneError& error) {
    return error.what();
  }
  return "";
}

// Without the buffers and images it names, a glTF file still shows its container, its
// JSON and the extensions it requires; a JSON scene its syntax.
TEST(FileSniffTest, AFileAloneIsCheckedAsFarAsItCanBe) {
  const std::string external =
      R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "mesh.bin", "byteLength": 12}]})";
  EXPECT_EQ(AloneRefusal(external, "shot.gltf"), "");
  EXPECT_NE(AloneRefusal("<html></html>", "shot.gltf").find("this is an HTML page"), std::string::npos);
  EXPECT_NE(AloneRefusal(R"({"asset": {"version": "2.0"}, )", "shot.gltf").find("the JSON does not parse"),
            std::string::npos);
  EXPECT_NE(AloneRefusal(R"({"asset": {"version": "2.0"}, "extensionsRequired": ["EXT_not_implemented_here"]})",
                         "shot.gltf")
                .find("requires extension \"EXT_not_implemented_here\""),
            std::string::npos);
  EXPECT_NE(AloneRefusal("glTF\x02\x00\x00\x00\x40\x00\x00\x00"s, "shot.glb").find("ends inside its header"), std::string::npos);
  EXPECT_EQ(AloneRefusal(R"({"shapes": [{"type": "mesh", "file": "a.obj"}]})", "scene.json"), "");
  EXPECT_NE(AloneRefusal(R"({"shapes": [)", "scene.json").find("scene.json: invalid JSON"), std::string::npos);
  EXPECT_NE(AloneRefusal("PK\x03\x04"s, "scene.json").find("this is a ZIP archive"), std::string::npos);
  EXPECT_EQ(AloneRefusal("mtllib missing.mtl\nv 0 0 0\n", "box.obj"), "");
}

}  // namespace
}  // namespace tcfarm
