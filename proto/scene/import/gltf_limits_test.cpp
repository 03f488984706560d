// Hostile glTF files: accessors that claim more elements than their buffer views hold, and
// data URIs, must be refused (or decoded) before anything is allocated per element, with
// a message that says what, where and what was expected. tests/gltf/test_gltf_memory.py
// measures the peak memory of the same kind of files in a real process.
#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/support/cpp/scene_test_support.h"
#include "proto/json/strict_json.h"
#include "proto/scene/import/scene_import.h"

namespace tcfarm {
namespace {

using nlohmann::json;



std::string Floats(const std::vector<float>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
}

// The probe's file: one animation whose key times and translations are accessors 0 and 1
// over buffer view 0, 36 bytes (three VEC3 floats, or nine floats).
json AnimatedNode() {
  const std::string data = Floats({0, 1, 2, 0, 0, 0, 1, 1, 1});
  return {{"asset", {{"version", "2.0"}}},
          {"scene", 0},
          {"scenes", {{{"nodes", {0}}}}},
          {"nodes", {{{"name", "mover"}}}},
          {"buffers", {{{"byteLength", data.size()}, {"uri", "data:application/octet-stream;base64," + Base64(data)}}}},
          {"bufferViews", {{{"buffer", 0}, {"byteLength", data.size()}}}},
          {"accessors",
           {{{"bufferView", 0}, {"componentType", 5126}, {"type", "SCALAR"}, {"count", 3}},
            {{"bufferView", 0}, {"componentType", 5126}, {"type", "VEC3"}, {"count", 3}}}},
          {"animations",
           {{{"samplers", {{{"input", 0}, {"output", 1}}}},
             {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}}}}}};
}

std::string ImportError(const json& gltf) {
  return ErrorOf([&] { ImportSceneBytes(gltf.dump(), "gltf"); });
}

void ExpectError(const std::string& what, const std::string& where, const std::string& problem,
                 const std::string& expected) {
  EXPECT_EQ(what.find("scene" + where + ": the gltf scene: "), 0u) << what;
  EXPECT_NE(what.find(problem), std::string::npos) << what;
  EXPECT_NE(what.find("; expected " + expected), std::string::npos) << what;
}

TEST(GltfLimitsTest, TheProbeFileImports) {
  const Scene scene = ImportSceneBytes(AnimatedNode().dump(), "gltf");
  EXPECT_EQ(scene.render.frameCount, 2 * 24 + 1);  // key times 0 to 2 s at 24 frames a second
}

TEST(GltfLimitsTest, CountsPastTheLimitAreRefusedBeforeAnyAllocation) {
  for (const uint64_t count : {uint64_t{1} << 28, uint64_t{1} << 30, uint64_t{1} << 31, uint64_t{1} << 40}) {
    json gltf = AnimatedNode();
    gltf["accessors"][0]["count"] = count;
    ExpectError(ImportError(gltf), "/accessors/0/count", std::to_string(count) + " elements",
                "at most 60000000 elements in one accessor");
  }
}

TEST(GltfLimitsTest, ElementsPastTheirViewAreRefused) {
  json gltf = AnimatedNode();
  gltf["accessors"][1]["count"] = 4;  // a fourth VEC3 would end at byte 48 of 36
  ExpectError(ImportError(gltf), "/accessors/1",
              "4 elements from byte 0 run past the end of buffer view 0 (36 bytes; elements of 12 bytes, 12 apart)",
              "an accessor inside its buffer view");
}

TEST(GltfLimitsTest, OffsetPastTheViewIsRefused) {
  json gltf = AnimatedNode();
  gltf["accessors"][0]["count"] = 1;
  gltf["accessors"][0]["byteOffset"] = 36;  // one float from byte 36 of 36
  ExpectError(ImportError(gltf), "/accessors/0", "1 elements from byte 36 run past the end of buffer view 0",
              "an accessor inside its buffer view");
}

TEST(GltfLimitsTest, ViewPastItsBufferIsRefused) {
  json gltf = AnimatedNode();
  gltf["bufferViews"][0]["byteLength"] = 100;
  gltf["bufferViews"][0]["byteOffset"] = 4;
  ExpectError(ImportError(gltf), "/bufferViews/0", "100 bytes from byte 4 of buffer 0 (36 bytes)",
              "a buffer view inside its buffer");
}

TEST(GltfLimitsTest, StrideTimesCountPastTheViewIsRefused) {
  // 2^24 elements 252 bytes apart: 4 GiB, past 32 bits, of a 36-byte view.
  json gltf = AnimatedNode();
  gltf["bufferViews"][0]["byteStride"] = 252;
  gltf["accessors"][0]["count"] = uint64_t{1} << 24;
  ExpectError(ImportError(gltf), "/accessors/0", "16777216 elements from byte 0 run past the end of buffer view 0",
              "an accessor inside its buffer view");
}

TEST(GltfLimitsTest, SparseViewsAreCheckedToo) {
  json gltf = AnimatedNode();
  gltf["accessors"][1]["sparse"] = {{"count", 2},
                                    {"indices", {{"bufferView", 0}, {"byteOffset", 34}, {"componentType", 5123}}},
                                    {"values", {{"bufferView", 0}}}};
  ExpectError(ImportError(gltf), "/accessors/1/sparse/indices", "2 elements from byte 34 run past the end",
              "an accessor inside its buffer view");
  gltf["accessors"][1]["sparse"]["indices"]["byteOffset"] = 0;
  gltf["accessors"][1]["sparse"]["values"]["byteOffset"] = 24;  // two VEC3s from byte 24 of 36
  ExpectError(ImportError(gltf), "/accessors/1/sparse/values", "2 elements from byte 24 run past the end",
              "an accessor inside its buffer view");
}

TEST(GltfLimitsTest, MeshAccessorsPassTheSameGate) {
  json gltf = AnimatedNode();
  gltf.erase("animations");
  gltf["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", 1}}}}}}}};
  gltf["nodes"][0]["mesh"] = 0;
  gltf["accessors"][1]["count"] = uint64_t{1} << 31;
  ExpectError(ImportError(gltf), "/accessors/1/count", "2147483648 elements", "at most 60000000 elements");
}

// A triangle soup of `triangles` triangles in one accessor, drawn by `meshes` meshes that
// all name it: a few bytes of JSON per mesh, the accessor's values each time.
json SharedAccessor(int triangles, int meshes) {
  std::vector<float> positions;
  for (int i = 0; i < 3 * triangles; ++i) positions.insert(positions.end(), {i % 3 == 1 ? 1.f : 0, i % 3 == 2 ? 1.f : 0, i * 1e-3f});
  const std::string data = Floats(positions);
  json gltf = {{"asset", {{"version", "2.0"}}},
               {"scene", 0},
               {"scenes", {{{"nodes", json::array()}}}},
               {"nodes", json::array()},
               {"meshes", json::array()},
               {"buffers", {{{"byteLength", data.size()}, {"uri", "data:application/octet-stream;base64," + Base64(data)}}}},
               {"bufferViews", {{{"buffer", 0}, {"byteLength", data.size()}}}},
               {"accessors", {{{"bufferView", 0}, {"componentType", 5126}, {"type", "VEC3"}, {"count", 3 * triangles}}}}};
  for (int m = 0; m < meshes; ++m) {
    gltf["meshes"].push_back({{"primitives", {{{"attributes", {{"POSITION", 0}}}}}}});
    gltf["nodes"].push_back({{"mesh", m}});
    gltf["scenes"][0]["nodes"].push_back(m);
  }
  return gltf;
}

TEST(GltfLimitsTest, OneAccessorReadOverAndOverIsRefused) {
  // 2.4 MB of values per read against 16 x 1.2 MB + 16 MiB: the 15th read is refused.
  EXPECT_NO_THROW(ImportSceneBytes(SharedAccessor(100000 / 3, 2).dump(), "gltf"));
  ExpectError(ImportError(SharedAccessor(100000 / 3, 40)), "/accessors/0",
              "reading it brings the values read from the file's accessors to",
              "at most 16 bytes of values per byte of the file's buffers");
}

TEST(GltfLimitsTest, DataUrisAreDecodedAsBase64) {
  json gltf = AnimatedNode();
  const std::string uri = gltf["buffers"][0]["uri"];
  // JSON may escape any character; the URI and its bytes are the same.
  std::string text = gltf.dump();
  text.replace(text.find("data:application/"), 17, "dat\\u0061:application\\/");
  EXPECT_EQ(ImportSceneBytes(text, "gltf").render.frameCount, 2 * 24 + 1);

  gltf["buffers"][0]["uri"] = uri.substr(0, uri.size() - 4) + "A!AA";
  std::string what = ImportError(gltf);
  EXPECT_NE(what.find("character \"!\" in a data URI's base64; expected a data URI of base64"), std::string::npos)
      << what;
  EXPECT_NE(what.find(": byte "), std::string::npos) << what;

  gltf["buffers"][0]["uri"] = uri;
  gltf["buffers"][0]["byteLength"] = 40;
  ExpectError(ImportError(gltf), "/buffers/0/byteLength", "a byteLength of 40 for a data URI of 36 bytes",
              "the byteLength its data URI decodes to");

  gltf["buffers"][0]["byteLength"] = 36;
  gltf["buffers"][0]["uri"] = "data:application/octet-stream,plain";
  EXPECT_NE(ImportError(gltf).find("that is not base64"), std::string::npos);
  gltf["buffers"][0]["uri"] = "tcfarm-embedded-data:0";
  EXPECT_NE(ImportError(gltf).find("in the form this importer reserves for itself"), std::string::npos);
}

// The probe file with `levels` arrays nested in its "extras": the document is `levels` + 1 deep.
std::string NestedExtras(size_t levels) {
  const std::string probe = AnimatedNode().dump();
  return probe.substr(0, probe.size() - 1) + R"(,"extras":)" + std::string(levels, '[') + std::string(levels, ']') +
         "}";
}

// A glTF file's JSON is nested no deeper than any JSON the farm reads (kMaxJsonDepth, an HTTP
// body's limit), checked before a parser builds it: a file nested a million levels deep was
// read whole, by two parsers, and imported.
TEST(GltfLimitsTest, JsonNestedDeeperThanAnyJsonTheFarmReadsIsRefusedWhereItGoesTooDeep) {
  EXPECT_EQ(ImportSceneBytes(NestedExtras(kMaxJsonDepth - 1), "gltf").render.frameCount, 2 * 24 + 1);
  // The container past the limit: the root, extras, then arrays at index 0.
  std::string tooDeep = "/extras";
  for (size_t level = 3; level <= kMaxJsonDepth + 1; ++level) tooDeep += "/0";
  const std::string refused = "scene" + tooDeep +
                              ": the gltf scene: objects and arrays nested deeper than 128 levels; expected at most "
                              "128 levels";
  EXPECT_EQ(ErrorOf([] { ImportSceneBytes(NestedExtras(kMaxJsonDepth), "gltf"); }), refused);
  EXPECT_EQ(ErrorOf([] { ImportSceneBytes(NestedExtras(1'000'000), "gltf"); }), refused);
  // A scene check of the file alone, before the files it names are uploaded, refuses it alike.
  EXPECT_EQ(ErrorOf([] { CheckSceneFileAlone(NestedExtras(1'000'000), "deep.gltf"); }),
            "scene" + tooDeep +
                ": deep.gltf: objects and arrays nested deeper than 128 levels; expected at most 128 levels");
}

}  // namespace
}  // namespace tcfarm
