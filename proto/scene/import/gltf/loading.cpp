// Reading the file: the GLB container, what tinygltf would report without a pointer, tinygltf itself.
#include "proto/scene/import/gltf/gltf_reader.h"

#include <fstream>

#include "proto/json/strict_json.h"
#include "proto/scene/import/file_sniff.h"
#include "proto/scene/import/gltf/file_access.h"
#include "proto/scene/import/import_budget.h"

namespace tcfarm::gltf {

GltfReader::GltfReader(const ImportInput& input) : input_(input), options_(input.options) {}

Scene GltfReader::Read() {
  // Held until the scene is made: the JSON with its data URIs decoded, the GLB tinygltf
  // reads when that changed, and tinygltf's buffers.
  ExtractDocument(3);
  StandInForFallbackBuffers();
  StandInForDracoIndexViews();
  PreCheck(embedded_.json);
  Load();
  embedded_ = {};
  CheckExtensions();
  fileBufferBytes_ = BufferBytes();
  DecodeMeshoptViews();
  DecodeDracoPrimitives();
  Scene scene;
  AddMaterials(scene);
  BuildGraph();
  ChooseAnimation();
  BuildMotions();
  AddShapes(scene);
  AddCamera(scene);
  AddLights(scene);
  scene.render.width = kDefaultWidth;
  scene.render.height = kDefaultHeight;
  scene.render.firstFrame = 0;
  scene.render.frameCount = FramesAsked();
  scene.importWarnings = warnings_;
  return scene;
}

[[noreturn]] void GltfReader::Fail(const std::string& pointer, const std::string& problem, const std::string& expected) const {
  FailInput(pointer, input_.displayName + ": " + problem, expected);
}

void GltfReader::Warn(const std::string& code, const std::string& pointer, const std::string& text) const {
  ImportWarning warning{code, input_.displayName, pointer, text};
  // A sampler or texture shared by many materials is said once.
  if (std::find(warnings_.begin(), warnings_.end(), warning) != warnings_.end()) return;
  warnings_.push_back(std::move(warning));
  std::fprintf(stderr, "warning: [%s] %s\n", code.c_str(), warnings_.back().Line().c_str());
}

bool GltfReader::IsBinary() const { return input_.bytes.compare(0, 4, "glTF") == 0; }

std::string_view GltfReader::CheckContainer() const {
  const std::string& bytes = input_.bytes;
  if (bytes.size() > std::numeric_limits<unsigned int>::max()) {
    Fail("", "the file holds " + std::to_string(bytes.size()) + " bytes", "a glTF file under 4 GiB");
  }
  // An HTML page or an archive named .glb is said to be one, before a parser trips on it.
  RequireGltfStart(bytes, input_.displayName);
  if (!IsBinary()) return bytes;
  auto word = [&](size_t offset) {
    uint32_t value = 0;
    for (int i = 3; i >= 0; --i) value = value << 8 | static_cast<unsigned char>(bytes[offset + i]);
    return value;
  };
  const std::string glb = "a GLB file: a 12-byte header, a JSON chunk, an optional BIN chunk";
  if (bytes.size() < 20)
    Fail("", "GLB byte " + std::to_string(bytes.size()) + ": the file ends inside its header", glb);
  if (word(4) != 2) Fail("", "GLB byte 4: version " + std::to_string(word(4)), "GLB version 2");
  if (word(8) != bytes.size()) {
    Fail("",
         "GLB byte 8: the header gives a length of " + std::to_string(word(8)) + " bytes but the file holds " +
             std::to_string(bytes.size()) + (word(8) > bytes.size() ? " (truncated)" : ""),
         glb);
  }
  uint32_t jsonLength = word(12);
  if (word(16) != 0x4E4F534Au) Fail("", "GLB byte 16: the first chunk is not JSON", glb);
  if (20 + static_cast<uint64_t>(jsonLength) > bytes.size()) {
    Fail("", "GLB byte 12: a JSON chunk of " + std::to_string(jsonLength) + " bytes runs past the end of the file",
         glb);
  }
  size_t next = 20 + jsonLength;
  if (next + 8 <= bytes.size()) {
    uint32_t binLength = word(next);
    if (next + 8 + static_cast<uint64_t>(binLength) > bytes.size()) {
      Fail("",
           "GLB byte " + std::to_string(next) + ": a chunk of " + std::to_string(binLength) +
               " bytes runs past the end of the file",
           glb);
    }
  } else if (next != bytes.size()) {
    Fail("", "GLB byte " + std::to_string(next) + ": the file ends inside a chunk header", glb);
  }
  return std::string_view(bytes).substr(20, jsonLength);
}

void GltfReader::ExtractDocument(uint64_t copiesOfTheFile) {
  ChargeImportMemory(copiesOfTheFile * input_.bytes.size());
  embedded_ = gltf::ExtractDataUris(CheckContainer(), input_.displayName);
  // Before any parser builds the document: one nested a million levels deep would cost
  // hundreds of megabytes to refuse, and more to destroy.
  try {
    CheckJsonNesting(embedded_.json);
  } catch (const JsonInputError& error) {
    Fail(error.pointer(), error.problem(), error.expected());
  }
  // This reader's document and tinygltf's, alive together while tinygltf builds its model.
  if (ChargingImportMemory()) ChargeImportMemory(2 * JsonDomBytes(embedded_.json));
}

namespace {

std::string SupportedExtensionList() {
  std::string list;
  for (const std::string& name : kSupportedExtensions) list += (list.empty() ? "" : ", ") + name;
  return list;
}

}  // namespace

void GltfReader::CheckAlone() {
  ExtractDocument(1);
  const nlohmann::json document = nlohmann::json::parse(embedded_.json, nullptr, false);
  CheckDocument(document);
  embedded_ = {};
}

void GltfReader::CheckDocument(const nlohmann::json& document) const {
  if (document.is_discarded()) {
    // The parser's own words, for the byte where it stopped (a syntax error), or for the
    // number it cannot hold (out_of_range, which is no parse_error).
    try {
      [[maybe_unused]] const nlohmann::json reparsed = nlohmann::json::parse(embedded_.json);
    } catch (const nlohmann::json::exception& error) {
      Fail("", "the JSON does not parse: " + StripJsonExceptionPrefix(error.what()), "glTF JSON");
    }
  }
  if (!document.is_object()) Fail("", std::string("the JSON is a ") + document.type_name(), "a glTF JSON object");
  CheckVersion(document);
  auto [pointer, expected] = WrongType(document, "root", "");
  if (!pointer.empty()) {
    Fail(pointer,
         std::string("a value of JSON type ") + document.at(nlohmann::json::json_pointer(pointer)).type_name(),
         expected);
  }
  if (document.contains("extensionsRequired") && document["extensionsRequired"].is_array()) {
    const auto& required = document["extensionsRequired"];
    for (size_t i = 0; i < required.size(); ++i) {
      if (required[i].is_string() && !kSupportedExtensions.count(required[i].get<std::string>())) {
        Fail("/extensionsRequired/" + std::to_string(i),
             "the file requires extension " + QuoteInput(required[i].get<std::string>()) +
                 ", which this importer does not implement",
             "only required extensions among " + SupportedExtensionList());
      }
    }
  }
}

void GltfReader::PreCheck(const std::string& jsonText) const {
  nlohmann::json document = nlohmann::json::parse(jsonText, nullptr, false);
  CheckDocument(document);
  for (const char* collection : {"buffers", "images"}) {
    if (!document.contains(collection) || !document[collection].is_array()) continue;
    const auto& items = document[collection];
    for (size_t i = 0; i < items.size(); ++i) {
      if (!items[i].is_object() || !items[i].contains("uri") || !items[i]["uri"].is_string()) continue;
      std::string uri = items[i]["uri"].get<std::string>();
      std::string pointer = Pointer(collection, i) + "/uri";
      if (const std::optional<size_t> embedded = gltf::EmbeddedIndex(uri)) {
        CheckEmbeddedLength(items[i], embedded_.bytes[*embedded].size(), Pointer(collection, i));
        continue;
      }
      if (uri.compare(0, 5, "data:") == 0) continue;  // one the scan did not take out (gltf_data_uris.h): tinygltf decodes it
      std::string what = std::string(collection) == "buffers" ? "buffer file" : "image file";
      if (!input_.baseDirectory) {
        Fail(pointer, what + " " + QuoteInput(uri) + " cannot be read: the file was submitted without a folder",
             "a self-contained glTF (data URIs or GLB), or one imported from a folder holding its files");
      }
      if (HasMalformedEscape(uri)) {
        Fail(pointer, what + " " + QuoteInput(uri) + " has a '%' that is not an escape",
             "a URI whose '%' each start an escape of two hex digits (a file named with '%' writes it %25)");
      }
      std::filesystem::path path;
      try {
        path = ResolveInsideFolder(*input_.baseDirectory, UrlDecode(uri), pointer, what);
      } catch (const SceneError& error) {
        Fail(pointer, std::string(error.what()).substr(("scene" + pointer + ": ").size()),
             "a file inside the scene folder");
      }
      std::error_code error;
      if (!std::filesystem::is_regular_file(path, error)) {
        Fail(pointer, what + " " + QuoteInput(uri) + " is missing", "a readable file inside the scene folder");
      }
    }
  }
}

void GltfReader::CheckVersion(const nlohmann::json& document) const {
  const std::string expected = "a glTF 2.0 file (asset.version \"2.0\")";
  if (!document.contains("asset")) Fail("", "no \"asset\" property", expected);
  if (!document["asset"].is_object()) return;  // the type check says so
  const nlohmann::json& asset = document["asset"];
  if (!asset.contains("version")) Fail("/asset", "no asset.version", expected);
  const nlohmann::json& version = asset["version"];
  if (version.is_string() && version.get<std::string>().compare(0, 2, "2.") == 0) return;
  const bool oneOh = version.is_string() ? version.get<std::string>().compare(0, 2, "1.") == 0
                                         : version.is_number() && version.get<double>() == 1;
  Fail("/asset/version",
       "version " + version.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace).substr(0, 40) +
           (oneOh ? ": a glTF 1.0 file, which this importer does not read" : ""),
       expected);
}

void GltfReader::CheckEmbeddedLength(const nlohmann::json& item, size_t decoded, const std::string& pointer) const {
  if (!item.contains("byteLength") || !item["byteLength"].is_number()) return;  // not a buffer
  const nlohmann::json& length = item["byteLength"];
  if (!length.is_number_unsigned() || length.get<uint64_t>() != decoded) {
    Fail(pointer + "/byteLength", "a byteLength of " + length.dump() + " for a data URI of " +
                                      std::to_string(decoded) + " bytes",
         "the byteLength its data URI decodes to");
  }
}

std::string GltfReader::GlbWithJson(const std::string& json) const {
  const std::string& bytes = input_.bytes;
  uint32_t oldLength = 0;
  for (int i = 3; i >= 0; --i) oldLength = oldLength << 8 | static_cast<unsigned char>(bytes[12 + i]);
  std::string padded = json + std::string((4 - json.size() % 4) % 4, ' ');
  const std::string_view rest = std::string_view(bytes).substr(20 + oldLength);
  auto word = [](uint64_t value) {
    std::string out(4, '\0');
    for (int i = 0; i < 4; ++i) out[i] = static_cast<char>(value >> (8 * i));
    return out;
  };
  std::string glb = bytes.substr(0, 8) + word(20 + padded.size() + rest.size()) + word(padded.size()) + "JSON";
  glb.reserve(glb.size() + padded.size() + rest.size());
  glb += padded;
  glb.append(rest);
  return glb;
}

void GltfReader::Load() {
  tinygltf::TinyGLTF loader;
  FileAccess access{input_.baseDirectory, "", &embedded_.bytes};
  std::string base;
  if (input_.baseDirectory) {
    base = input_.baseDirectory->string();
    access.prefix = base + "/";
  }
  loader.SetFsCallbacks({&FileExistsInside, &ExpandNothing, &ReadFileInside, &WriteNothing, &access});
  loader.SetImageLoader(&KeepImageEncoded, &model_);
  std::string error, warning;
  bool loaded = false;
  if (IsBinary()) {
    // Rebuilt when its JSON changed: data URIs taken out, or stand-ins put in (meshopt's
    // fallback buffers, Draco's index views), which a GLB without data URIs may need too.
    const bool changed = embedded_.json != CheckContainer();
    const std::string rebuilt = changed ? GlbWithJson(embedded_.json) : "";
    const std::string& glb = changed ? rebuilt : input_.bytes;
    loaded = loader.LoadBinaryFromMemory(&model_, &error, &warning,
                                         reinterpret_cast<const unsigned char*>(glb.data()),
                                         static_cast<unsigned int>(glb.size()), base, tinygltf::REQUIRE_VERSION);
  } else {
    loaded = loader.LoadASCIIFromString(&model_, &error, &warning, embedded_.json.data(),
                                        static_cast<unsigned int>(embedded_.json.size()), base,
                                        tinygltf::REQUIRE_VERSION);
  }
  auto oneLine = [](std::string text) {
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    std::replace(text.begin(), text.end(), '\n', ' ');
    return text;
  };
  if (!loaded) Fail("", "tinygltf cannot read it: " + oneLine(error), "a valid glTF 2.0 file");
  if (!warning.empty()) Warn("loader_warning", "", "tinygltf: " + oneLine(warning));
}

void GltfReader::CheckExtensions() const {
  for (size_t i = 0; i < model_.extensionsRequired.size(); ++i) {
    if (!kSupportedExtensions.count(model_.extensionsRequired[i])) {
      Fail("/extensionsRequired/" + std::to_string(i),
           "the file requires extension " + QuoteInput(model_.extensionsRequired[i]) +
               ", which this importer does not implement",
           "only required extensions this importer implements");
    }
  }
  // An optional extension the importer does not know is left out, and the picture may
  // differ from what the file means: said, never silent.
  for (size_t i = 0; i < model_.extensionsUsed.size(); ++i) {
    if (!kSupportedExtensions.count(model_.extensionsUsed[i])) {
      Warn("extension_not_implemented", "/extensionsUsed/" + std::to_string(i), "extension " + QuoteInput(model_.extensionsUsed[i]) +
                                                       " is not implemented; what it adds is left out");
    }
  }
}

}  // namespace tcfarm::gltf
