#include "coordinator/http/submit_request.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include "proto/frame/encoded_image.h"
#include "proto/frame/view_transform.h"
#include "coordinator/http/api_error.h"
#include "coordinator/http/job_json.h"
#include "proto/json/strict_json.h"
#include "proto/scene/import/gltf_data_uris.h"
#include "proto/scene/import/import_budget.h"
#include "proto/scene/import/import_options.h"
#include "proto/scene/import/scene_import.h"
#include "proto/scene/scene.h"
#include "proto/scene/scene_limits.h"
#include "proto/wire/content_hash.h"
#include "coordinator/store/frame_finisher.h"

namespace tcfarm::http {
namespace {

using nlohmann::json;

constexpr const char* kTopLevelFields[] = {"scene",     "name",      "frames",   "strategy",
                                           "bin_width", "tolerance", "priority", "verify",
                                           "spot_check_share", "assets", "scene_file", "import",
                                           "view",      "exposure"};
constexpr int kDefaultBinWidth = 10;

// Messages read like the scene parser's: "<pointer without the leading '/'>: <problem>;
// expected <what>", so a client sees one style for every field.
// Control bytes in a key (an asset path may hold a NUL) written as JSON writes them: a raw
// NUL would end the message where std::exception::what() stops reading.
std::string EscapeControlBytes(const std::string& text) {
  std::string escaped;
  for (char c : text) {
    if (static_cast<unsigned char>(c) < 0x20) {
      char code[8];
      std::snprintf(code, sizeof code, "\\u%04x", static_cast<unsigned>(c));
      escaped += code;
    } else {
      escaped += c;
    }
  }
  return escaped;
}

[[noreturn]] void Fail(const char* code, const std::string& pointer, const std::string& problem,
                       const std::string& expected) {
  const std::string where = pointer.empty() ? "request body" : EscapeControlBytes(pointer.substr(1));
  throw ApiError(400, code, where + ": " + problem + "; expected " + expected, pointer);
}


// Duplicate keys are refused here, at the body: the scene inside it is re-serialized
// before ParseScene sees it, so the scene's own check could not catch them.
json ParseBody(const std::string& body) {
  try {
    return ParseStrictJson(body);
  } catch (const JsonInputError& error) {
    if (error.pointer().empty() || error.problem().rfind("duplicate", 0) != 0) {
      throw ApiError(400, error_code::kInvalidJson,
                     "request body is not valid JSON: " + std::string(error.what()),
                     error.pointer().empty() ? std::nullopt : std::optional(error.pointer()));
    }
    Fail(error_code::kInvalidJson, error.pointer(), error.problem(), error.expected());
  }
}

bool IsIntegral(const json& value) {
  if (value.is_number_integer()) return true;
  if (!value.is_number_float()) return false;
  const double number = value.get<double>();
  return std::isfinite(number) && std::floor(number) == number;
}

int ReadInteger(const json& value, const std::string& pointer, int low, int high,
                const std::string& expected) {
  if (!IsIntegral(value)) {
    Fail(error_code::kInvalidField, pointer, ShowValue(value) + " is not an integer", expected);
  }
  // The limits are far below 2^53, so comparing as double is exact where it matters.
  const double number = value.get<double>();
  if (number < low || number > high) {
    Fail(error_code::kInvalidField, pointer, ShowValue(value) + " is out of range", expected);
  }
  return static_cast<int>(number);
}

std::string IntegerRange(int low, int high) {
  return "an integer in [" + std::to_string(low) + ", " + std::to_string(high) + "]";
}

// Every member of `object` (at `pointer`) is one of `fields`.
template <typename Fields>
void CheckKnownFields(const json& object, const std::string& pointer, const Fields& fields) {
  std::string known;
  for (const char* field : fields) known += std::string(known.empty() ? "" : ", ") + field;
  for (const auto& item : object.items()) {
    bool isKnown = false;
    for (const char* field : fields) isKnown = isKnown || item.key() == field;
    if (!isKnown) {
      Fail(error_code::kUnknownField, pointer + "/" + EscapePointerToken(item.key()), "unknown field",
           "only the fields " + known);
    }
  }
}

std::string ReadName(const json& request) {
  const auto name = request.find("name");
  if (name == request.end()) return "";
  const std::string expected = "a string of at most " + std::to_string(kMaxNameBytes) + " bytes";
  if (!name->is_string()) {
    Fail(error_code::kInvalidField, "/name", ShowValue(*name) + " is not a string", expected);
  }
  if (name->get_ref<const std::string&>().size() > kMaxNameBytes) {
    Fail(error_code::kInvalidField, "/name", "the name is too long", expected);
  }
  return name->get<std::string>();
}

Strategy ReadStrategy(const json& request) {
  const auto strategy = request.find("strategy");
  if (strategy == request.end()) return kDefaultStrategy;
  if (strategy->is_string()) {
    if (std::optional<Strategy> known = StrategyFromString(strategy->get_ref<const std::string&>())) {
      return *known;
    }
  }
  std::string expected = "one of";
  for (const StrategyNameEntry& entry : kStrategyNames) {
    expected += std::string(expected == "one of" ? " \"" : ", \"") + std::string(entry.name) + "\"";
  }
  Fail(error_code::kInvalidField, "/strategy", ShowValue(*strategy) + " is not a supported strategy", expected);
}

int ReadOptionalInteger(const json& request, const char* field, int low, int high, int fallback) {
  const auto value = request.find(field);
  if (value == request.end()) return fallback;
  return ReadInteger(*value, std::string("/") + field, low, high, IntegerRange(low, high));
}

double ReadTolerance(const json& request) {
  const auto tolerance = request.find("tolerance");
  if (tolerance == request.end()) return 0;
  // Pixel values are floats: a tolerance beyond the largest float compares nothing more.
  const std::string expected = "a number in [0, 3.4028234663852886e38]";
  if (!tolerance->is_number()) {
    Fail(error_code::kInvalidField, "/tolerance", ShowValue(*tolerance) + " is not a number", expected);
  }
  const double value = tolerance->get<double>();
  if (!(value >= 0 && value <= std::numeric_limits<float>::max())) {
    Fail(error_code::kInvalidField, "/tolerance", ShowValue(*tolerance) + " is out of range", expected);
  }
  return value;
}

// "view" and "exposure": how the job's PNG previews show its linear frames (view_transform.h).
ViewTransform ReadPreviewView(const json& request) {
  ViewTransform view;
  if (const auto name = request.find("view"); name != request.end()) {
    const std::string expected = "one of " + ViewNames();
    if (!name->is_string()) Fail(error_code::kInvalidField, "/view", ShowValue(*name) + " is not a string", expected);
    const std::optional<View> known = ParseView(name->get<std::string>());
    if (!known) Fail(error_code::kInvalidField, "/view", ShowValue(*name) + " is not a view", expected);
    view.view = *known;
  }
  if (const auto exposure = request.find("exposure"); exposure != request.end()) {
    const std::string bound = std::to_string(static_cast<int>(kMaxExposure));
    const std::string expected = "a number of stops in [-" + bound + ", " + bound + "]";
    if (!exposure->is_number()) {
      Fail(error_code::kInvalidField, "/exposure", ShowValue(*exposure) + " is not a number", expected);
    }
    if (!IsValidExposure(exposure->get<double>())) {
      Fail(error_code::kInvalidField, "/exposure", ShowValue(*exposure) + " is out of range", expected);
    }
    view.exposure = exposure->get<double>();
  }
  return view;
}

// The assets a submission names, checked (paths, hashes, presence, total size) before
// anything is laid out on disk.
// missing: where a check (not a submission) lists the paths whose hash the store lacks, to
// check the scene without them; null: such a hash is refused as missing_asset.
std::map<std::string, std::string> ReadAssets(const json& request, const SubmissionAssets& assets,
                                              std::vector<std::string>* missing = nullptr) {
  const auto field = request.find("assets");
  if (field == request.end()) return {};
  const std::string expected = "an object mapping relative paths to SHA-256 hashes of uploaded assets";
  if (!field->is_object()) {
    Fail(error_code::kInvalidField, "/assets", ShowValue(*field) + " is not an object", expected);
  }
  if (field->size() > kMaxAssetsPerJob) {
    Fail(error_code::kInvalidField, "/assets", std::to_string(field->size()) + " assets are too many",
         "at most " + std::to_string(kMaxAssetsPerJob) + " assets in one job");
  }
  if (assets.store == nullptr && !field->empty()) {
    Fail(error_code::kInvalidField, "/assets", "this coordinator has no asset store", "a self-contained scene");
  }
  std::map<std::string, std::string> files;
  uint64_t totalBytes = 0;
  for (const auto& item : field->items()) {
    const std::string& path = item.key();
    const std::string pointer = "/assets/" + EscapePointerToken(path);
    if (std::optional<std::string> problem = AssetPathProblem(path)) {
      Fail(error_code::kInvalidField, pointer, "asset path " + ShowValue(path) + " is refused: " + *problem,
           "a relative path inside the scene's folder, '/'-separated, without \".\", \"..\" or empty "
           "components, at most " + std::to_string(kMaxAssetPathBytes) + " bytes");
    }
    const json& hash = item.value();
    if (!hash.is_string() || !IsAssetHash(hash.get_ref<const std::string&>())) {
      Fail(error_code::kInvalidField, pointer, ShowValue(hash) + " is not a SHA-256",
           "64 lowercase hex characters, the hash of an uploaded asset");
    }
    const std::optional<uint64_t> size = assets.store->SizeOf(hash.get<std::string>());
    if (!size && missing != nullptr) {
      missing->push_back(path);
      continue;
    }
    if (!size) {
      Fail(error_code::kMissingAsset, pointer, "the farm has no asset " + hash.get<std::string>(),
           "an asset uploaded first with PUT /api/v1/assets/" + hash.get<std::string>());
    }
    totalBytes += *size;
    files.emplace(path, hash.get<std::string>());
  }
  if (assets.maxJobBytes != 0 && totalBytes > assets.maxJobBytes) {
    char total[32];
    std::snprintf(total, sizeof total, "%.1f", static_cast<double>(totalBytes) / (1u << 20));
    throw ApiError(413, error_code::kJobTooLarge,
                   "assets: the job's assets total " + std::string(total) + " MiB (" + std::to_string(totalBytes) +
                       " bytes); the coordinator allows " + std::to_string(assets.maxJobBytes >> 20) +
                       " MiB per job (" + assets.maxJobFlag + "); expected fewer or smaller assets",
                   "/assets");
  }
  return files;
}

Scene ReadInlineScene(const json& scene, const std::optional<std::filesystem::path>& folder) {
  try {
    // Without assets there is no folder: a scene from the network then inlines its meshes,
    // and can never name a file on the coordinator's disk.
    return ParseScene(scene.dump(), folder);
  } catch (const SceneError& error) {
    // SceneError's text already reads "scene<pointer>: ...", which is this body's pointer.
    throw ApiError(400, error_code::kInvalidScene, error.what(), "/scene" + error.pointer());
  }
}

// One member of "import", read by the scene's own reader of these options (import_options.h).
void ReadImportOption(const std::string& key, const json& value, ImportOptions& options) {
  const std::string pointer = "/import/" + EscapePointerToken(key);
  if (key == "fps") {
    options.framesPerSecond = ReadFramesPerSecond(value, pointer);
  } else if (key == "size") {
    if (!value.is_array() || value.size() != 2) {
      Fail(error_code::kInvalidField, pointer, ShowValue(value) + " is not a size", "[width, height]");
    }
    options.width = ReadImageSide(value[0], pointer + "/0");
    options.height = ReadImageSide(value[1], pointer + "/1");
  } else if (key == "animation" || key == "camera") {
    (key == "animation" ? options.animation : options.camera) = ReadNameOrIndex(value, pointer);
  } else if (key == "spp") {
    options.samplesPerPixel = ReadSamplesPerPixel(value, pointer);
  } else if (key == "light_units") {
    options.lightUnits = ReadLightUnits(value, pointer);
  } else {
    Fail(error_code::kUnknownField, pointer, "unknown field",
         "only the fields fps, size, animation, camera, spp, light_units");
  }
}

// "import": how a scene_file becomes a scene, as tcfarm-worker render's flags say it:
// {"fps": F, "size": [W, H], "animation": name or index, "camera": name or index, "spp": N}.
ImportOptions ReadImportOptions(const json& request) {
  ImportOptions options;
  const auto import = request.find("import");
  if (import == request.end()) return options;
  const std::string expected = R"({"fps", "size": [width, height], "animation", "camera", "spp", "light_units"})";
  if (!import->is_object()) Fail(error_code::kInvalidField, "/import", ShowValue(*import) + " is not an object", expected);
  if (request.find("scene_file") == request.end()) {
    Fail(error_code::kInvalidField, "/import", "given without a scene_file", "import options only with \"scene_file\"");
  }
  try {
    for (const auto& item : import->items()) ReadImportOption(item.key(), item.value(), options);
  } catch (const SceneError& error) {
    // The scene's reader words the problem; the API's style names the pointer without "scene".
    const std::string prefix = "scene" + error.pointer() + ": ";
    throw ApiError(400, error_code::kInvalidField,
                   error.pointer().substr(1) + ": " + std::string(error.what()).substr(prefix.size()), error.pointer());
  }
  return options;
}

// "scene_file": one of the assets, in any format the import seam reads (tcfarm JSON, OBJ, glTF).
Scene ReadSceneFromFile(const json& sceneFile, const std::set<std::string>& present,
                        const std::optional<std::filesystem::path>& folder, const ImportOptions& options) {
  const std::string expected = "the path of a scene file among the submission's assets";
  if (!sceneFile.is_string()) {
    Fail(error_code::kInvalidField, "/scene_file", ShowValue(sceneFile) + " is not a string", expected);
  }
  const std::string& path = sceneFile.get_ref<const std::string&>();
  if (present.count(path) == 0 || !folder) {
    Fail(error_code::kInvalidField, "/scene_file", ShowValue(path) + " is not among the assets", expected);
  }
  try {
    return ImportScene(*folder / std::filesystem::path(path), options);
  } catch (const SceneError& error) {
    throw ApiError(400, error_code::kInvalidScene, error.what(), "/scene_file");
  }
}

std::string TexturePointer(const Material& material, const std::string& where, const std::string& scenePointer) {
  return scenePointer == "/scene" ? "/scene/materials/" + EscapePointerToken(material.name) + "/" + where
                                  : scenePointer;
}

std::string ReadWholeFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw std::runtime_error("cannot read " + path.string());
  return bytes;
}

// A texture's image as its file's bytes: the file the scene names, the bytes a glTF file
// embeds, or the asset the store holds under the hash the scene names.
std::string TextureBytes(const Texture& texture, const AssetStore& store) {
  if (texture.bytes) return *texture.bytes;
  return ReadWholeFile(texture.asset.empty() ? texture.file : store.PathOf(texture.asset));
}

// Workers receive a scene as self-contained JSON: meshes travel inline, texture images by
// hash (they fetch them from the store). So every texture is named by the hash of its
// image's bytes here, and the store is made to hold them: an image file of the
// submission's folder is there already, one embedded in a glTF file is stored now. Each
// image is decoded once here, so that one no worker could read fails the submission, not
// every task of the job.
// keep false (a check): the images are read and decoded as for a job, and nothing is stored.
void BindTextureToAsset(const Material& material, Texture& texture, const std::string& where, AssetStore* store,
                        const std::string& scenePointer, bool keep) {
  const std::string pointer = TexturePointer(material, where, scenePointer);
  if (!store) {
    throw ApiError(400, error_code::kInvalidScene,
                   pointer.substr(1) + ": texture " + ShowValue(texture.Describe()) +
                       " cannot reach the workers of a farm without an asset store; expected a material without a texture",
                   pointer);
  }
  const bool namedByHash = !texture.asset.empty() && !texture.bytes;
  if (namedByHash && !store->Has(texture.asset)) {
    throw ApiError(400, error_code::kMissingAsset,
                   pointer.substr(1) + "/asset: the farm has no asset " + texture.asset +
                       "; expected the hash of an image uploaded first (PUT /api/v1/assets/{sha256})",
                   scenePointer == "/scene" ? pointer + "/asset" : pointer);
  }
  std::string bytes;
  try {
    bytes = TextureBytes(texture, *store);
  } catch (const std::runtime_error& error) {
    throw ApiError(507, error_code::kInsufficientStorage, std::string("the store could not read a texture: ") + error.what());
  }
  // Its pixels, held only while they are decoded: a scene's textures are checked one by one.
  const ImportReservation decoding = ReserveImportMemory(EncodedImageDecodeBytes(bytes));
  if (const auto problem = EncodedImageProblem(bytes)) {
    throw ApiError(400, error_code::kInvalidScene,
                   pointer.substr(1) + ": texture image " + ShowValue(texture.Describe()) + " cannot be used: " +
                       *problem + "; expected a PNG, JPEG or WebP image",
                   pointer);
  }
  if (namedByHash || !keep) return;
  texture.asset = wire::Sha256Hex(bytes);
  try {
    if (!store->Has(texture.asset) && store->Put(texture.asset, bytes) == AssetStore::CommitResult::kHashMismatch) {
      throw std::runtime_error("its bytes changed while they were stored");
    }
  } catch (const std::runtime_error& error) {
    throw ApiError(507, error_code::kInsufficientStorage,
                   "the store could not keep texture " + texture.Describe() + ": " + error.what());
  }
}

void BindTexturesToAssets(Scene& scene, AssetStore* store, const std::string& scenePointer, bool keep = true) {
  for (Material& material : scene.materials) {
    material.ForEachTexture([&](Texture& texture, const std::string& where) {
      BindTextureToAsset(material, texture, where, store, scenePointer, keep);
    });
  }
}

std::pair<int, int> ReadFrameRange(const json& request, const RenderSettings& render) {
  const int first = render.firstFrame;
  const int last = render.LastFrame();
  const auto frames = request.find("frames");
  if (frames == request.end()) return {first, last};
  if (!frames->is_object()) {
    Fail(error_code::kInvalidField, "/frames", ShowValue(*frames) + " is not an object",
         "{\"start\": first frame, \"end\": last frame}, both inclusive");
  }
  constexpr const char* kFrameFields[] = {"start", "end"};
  CheckKnownFields(*frames, "/frames", kFrameFields);
  const std::string inScene = "an integer in the scene's frame range [" + std::to_string(first) +
                              ", " + std::to_string(last) + "]";
  const int start = frames->contains("start")
                        ? ReadInteger(frames->at("start"), "/frames/start", first, last, inScene)
                        : first;
  const int end = frames->contains("end")
                      ? ReadInteger(frames->at("end"), "/frames/end", first, last, inScene)
                      : last;
  if (end < start) {
    Fail(error_code::kInvalidField, "/frames/end",
         std::to_string(end) + " is before frames/start " + std::to_string(start),
         "an end frame at or after the start frame");
  }
  return {start, end};
}

// The "frames" end asked for, before the scene is read: a glTF file's frames extend to it
// past the animation's end (ImportOptions::lastFrame). -1 when absent or not a frame a scene
// may have; ReadFrameRange then says what is wrong with it.
int RequestedLastFrame(const json& request) {
  const auto frames = request.find("frames");
  if (frames == request.end() || !frames->is_object()) return -1;
  const auto end = frames->find("end");
  if (end == frames->end() || !end->is_number_integer()) return -1;
  const int64_t last = end->get<int64_t>();
  return last >= 0 && last < scene_limits::kMaxFrameCount ? static_cast<int>(last) : -1;
}

// "verify": {"frames": "all"} or {"sample": K}: frames also rendered brute force and
// compared. Stored in the job's options for the farm.
json ReadVerify(const json& request) {
  const auto verify = request.find("verify");
  if (verify == request.end()) return nullptr;
  const std::string expected = R"({"frames": "all"} or {"sample": K} with K in [1, 100000])";
  if (!verify->is_object() || verify->size() != 1) {
    Fail(error_code::kInvalidField, "/verify", ShowValue(*verify) + " is not a verification request",
         expected);
  }
  if (verify->contains("frames")) {
    if ((*verify)["frames"] != "all") {
      Fail(error_code::kInvalidField, "/verify/frames", ShowValue((*verify)["frames"]) + " is not \"all\"",
           expected);
    }
    return {{"frames", "all"}};
  }
  if (!verify->contains("sample")) {
    Fail(error_code::kUnknownField, "/verify/" + verify->begin().key(), "unknown field", expected);
  }
  return {{"sample", ReadInteger((*verify)["sample"], "/verify/sample", 1, 100000, expected)}};
}

// Share of copied pixels traced again as spot checks, at most 2 %.
json ReadSpotCheckShare(const json& request) {
  const auto share = request.find("spot_check_share");
  if (share == request.end()) return nullptr;
  if (!share->is_number()) {
    Fail(error_code::kInvalidField, "/spot_check_share", ShowValue(*share) + " is not a number", "a number in [0, 0.02]");
  }
  if (!std::isfinite(share->get<double>()) || share->get<double>() < 0 || share->get<double>() > 0.02) {
    Fail(error_code::kInvalidField, "/spot_check_share", ShowValue(*share) + " is out of range",
         "a number in [0, 0.02]");
  }
  return *share;
}

// The body of a submission or a check: a JSON object of known fields.
json ReadRequestObject(const std::string& body, const std::vector<const char*>& fields) {
  json request = ParseBody(body);
  if (!request.is_object()) {
    Fail(error_code::kInvalidField, "", ShowValue(request) + " is not an object",
         "a JSON object with at least a \"scene\"");
  }
  CheckKnownFields(request, "", fields);
  return request;
}

// The job's own fields, read before the scene: cheap, so a typo in one of them is reported
// before a long scene parse.
JobSpec ReadJobFields(const json& request) {
  JobSpec spec;
  spec.name = ReadName(request);
  spec.strategy = ReadStrategy(request);
  spec.binWidth = ReadOptionalInteger(request, "bin_width", kMinBinWidth, kMaxBinWidth, kDefaultBinWidth);
  spec.tolerance = ReadTolerance(request);
  spec.priority = ReadOptionalInteger(request, "priority", kMinPriority, kMaxPriority, 0);
  spec.options = json::object();
  if (json verify = ReadVerify(request); !verify.is_null()) spec.options["verify"] = verify;
  if (json share = ReadSpotCheckShare(request); !share.is_null()) {
    spec.options["spot_check_share"] = share;
  }
  SetJobPreviewView(spec, ReadPreviewView(request));
  return spec;
}

void RequireOneScene(const json& request) {
  const bool inlineScene = request.contains("scene");
  const bool sceneFile = request.contains("scene_file");
  if (!inlineScene && !sceneFile) Fail(error_code::kMissingField, "/scene", "missing", "a scene object (proto/scene.md)");
  if (inlineScene && sceneFile) {
    Fail(error_code::kInvalidField, "/scene_file", "given beside an inline scene",
         "either \"scene\" or \"scene_file\", not both");
  }
}

// The submission's files laid out under their paths; removed when the result goes, whether
// the scene parses or not. None without files.
std::unique_ptr<AssetStore::Folder> LayOut(const std::map<std::string, std::string>& files, AssetStore* store) {
  if (files.empty()) return nullptr;
  try {
    return store->Materialise(files);
  } catch (const std::invalid_argument& error) {
    // ReadAssets checked each path and hash; what is left is a path that is another's folder.
    throw ApiError(400, error_code::kInvalidField, std::string("assets: ") + error.what() +
                                                       "; expected paths that name files, not folders of other paths",
                   "/assets");
  } catch (const std::runtime_error& error) {
    throw ApiError(507, error_code::kInsufficientStorage,
                   std::string("the store could not lay out the assets: ") + error.what());
  }
}

std::optional<std::filesystem::path> PathOf(const std::unique_ptr<AssetStore::Folder>& folder) {
  return folder ? std::optional<std::filesystem::path>(folder->path()) : std::nullopt;
}

std::set<std::string> PathsOf(const std::map<std::string, std::string>& files) {
  std::set<std::string> paths;
  for (const auto& [path, hash] : files) paths.insert(path);
  return paths;
}

// "scene_file_data": the scene file's bytes in base64 (RFC 4648, with padding), for a check
// before the file is uploaded.
std::string DecodeSceneFileData(const json& data) {
  const std::string expected = "the scene file's bytes in base64 (A-Z, a-z, 0-9, +, /, '=' padding)";
  if (!data.is_string()) Fail(error_code::kInvalidField, "/scene_file_data", ShowValue(data) + " is not a string", expected);
  const std::string& text = data.get_ref<const std::string&>();
  if (text.size() % 4 != 0) Fail(error_code::kInvalidField, "/scene_file_data", "its length is not a multiple of 4", expected);
  const size_t padding = text.size() - std::min(text.find_last_not_of('=') + 1, text.size());
  if (padding > 2) Fail(error_code::kInvalidField, "/scene_file_data", "it ends in more than two '='", expected);
  std::string bytes;
  bytes.reserve(text.size() / 4 * 3);
  uint32_t bits = 0;
  int pending = 0;
  for (size_t i = 0; i + padding < text.size(); ++i) {
    const int value = gltf::Base64Value(static_cast<unsigned char>(text[i]));
    if (value < 0) {
      Fail(error_code::kInvalidField, "/scene_file_data", "character " + std::to_string(i) + " is not base64", expected);
    }
    bits = bits << 6 | static_cast<uint32_t>(value);
    pending += 6;
    if (pending >= 8) {
      pending -= 8;
      bytes += static_cast<char>(bits >> pending & 0xFF);
    }
  }
  return bytes;
}

// The check's scene file and its bytes: given inline, or the asset of that path the store
// has; nullopt for an inline scene, or a scene file that is neither.
std::optional<std::string> SceneFileBytes(const json& request, const std::map<std::string, std::string>& files,
                                          const AssetStore& store) {
  if (const auto data = request.find("scene_file_data"); data != request.end()) return DecodeSceneFileData(*data);
  const auto sceneFile = request.find("scene_file");
  if (sceneFile == request.end() || !sceneFile->is_string()) return std::nullopt;
  const auto file = files.find(sceneFile->get<std::string>());
  if (file == files.end()) return std::nullopt;
  return ReadWholeFile(store.PathOf(file->second));
}

// The inline scene file's path, checked as an asset's path is: it is laid out beside them.
std::string InlineScenePath(const json& request, const SubmissionAssets& assets) {
  if (!request.contains("scene_file")) {
    Fail(error_code::kMissingField, "/scene_file", "missing beside scene_file_data", "the scene file's path");
  }
  if (assets.store == nullptr) {
    Fail(error_code::kInvalidField, "/scene_file_data", "this coordinator has no asset store", "a self-contained scene");
  }
  const json& path = request.at("scene_file");
  if (!path.is_string() || AssetPathProblem(path.get<std::string>())) {
    Fail(error_code::kInvalidField, "/scene_file", ShowValue(path) + " is not a path a scene file may have",
         "a relative path, '/'-separated, without \".\", \"..\" or empty components");
  }
  return path.get<std::string>();
}

void WriteFile(const std::filesystem::path& path, const std::string& bytes) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw ApiError(507, error_code::kInsufficientStorage, "the store could not lay out the scene file to check");
}

}  // namespace

JobSpec ParseSubmission(const std::string& body, const SubmissionAssets& assets) {
  const json request =
      ReadRequestObject(body, std::vector<const char*>(std::begin(kTopLevelFields), std::end(kTopLevelFields)));
  JobSpec spec = ReadJobFields(request);
  RequireOneScene(request);
  const auto inlineScene = request.find("scene");
  ImportOptions importOptions = ReadImportOptions(request);
  importOptions.lastFrame = RequestedLastFrame(request);
  const std::map<std::string, std::string> files = ReadAssets(request, assets);
  const std::unique_ptr<AssetStore::Folder> folder = LayOut(files, assets.store);
  Scene scene = inlineScene != request.end() ? ReadInlineScene(*inlineScene, PathOf(folder))
                                             : ReadSceneFromFile(request.at("scene_file"), PathsOf(files), PathOf(folder),
                                                                 importOptions);
  BindTexturesToAssets(scene, assets.store, inlineScene != request.end() ? "/scene" : "/scene_file");
  // What the import left out reaches the user with the job, not only the coordinator's log.
  if (!scene.importWarnings.empty()) spec.options["import_warnings"] = ImportWarningsJson(scene.importWarnings);
  std::tie(spec.firstFrame, spec.lastFrame) = ReadFrameRange(request, scene.render);
  // The canonical text, not the client's: equal scenes get equal hashes, whatever their
  // key order or spacing, so workers cache them once.
  spec.sceneJson = SerializeScene(scene);
  spec.sceneHash = wire::Sha256Hex(spec.sceneJson);
  spec.frameSize = FrameSize{scene.render.width, scene.render.height};
  spec.cameraOrLightsChange = scene.CameraMoves() || scene.AnyLightChanges();
  spec.deformingMeshes = std::any_of(scene.shapes.begin(), scene.shapes.end(),
                                     [](const Shape& shape) { return shape.Deforms(); });
  // What the job names in the store: the files it was submitted with and the textures its
  // workers fetch. An asset goes with the last job that names it.
  std::set<std::string> named;
  for (const auto& [path, hash] : files) named.insert(hash);
  for (const Material& material : scene.materials) {
    material.ForEachTexture([&](const Texture& texture, const std::string&) {
      if (!texture.asset.empty()) named.insert(texture.asset);
    });
  }
  spec.assetHashes.assign(named.begin(), named.end());
  return spec;
}

SceneCheck CheckSubmission(const std::string& body, const SubmissionAssets& assets) {
  std::vector<const char*> fields(std::begin(kTopLevelFields), std::end(kTopLevelFields));
  fields.push_back("scene_file_data");
  const json request = ReadRequestObject(body, fields);
  ReadJobFields(request);
  RequireOneScene(request);
  const auto inlineScene = request.find("scene");
  ImportOptions importOptions = ReadImportOptions(request);
  importOptions.lastFrame = RequestedLastFrame(request);
  SceneCheck check;
  std::map<std::string, std::string> files = ReadAssets(request, assets, &check.missingAssets);
  const bool inlineFile = request.contains("scene_file_data");
  const std::string inlinePath = inlineFile ? InlineScenePath(request, assets) : "";
  if (!check.missingAssets.empty()) {
    // Without those files only what the scene file alone shows can be checked.
    check.complete = false;
    if (const std::optional<std::string> bytes = SceneFileBytes(request, files, *assets.store)) {
      try {
        CheckSceneFileAlone(*bytes, request.at("scene_file").get<std::string>());
      } catch (const SceneError& error) {
        throw ApiError(400, error_code::kInvalidScene, error.what(), "/scene_file");
      }
    }
    return check;
  }
  if (inlineFile) files.erase(inlinePath);  // the inline bytes are the ones to check
  std::unique_ptr<AssetStore::Folder> folder = LayOut(files, assets.store);
  std::set<std::string> present = PathsOf(files);
  if (inlineFile) {
    if (!folder) folder = assets.store->Materialise({});
    WriteFile(folder->path() / std::filesystem::path(inlinePath), DecodeSceneFileData(request.at("scene_file_data")));
    present.insert(inlinePath);
  }
  Scene scene = inlineScene != request.end()
                    ? ReadInlineScene(*inlineScene, PathOf(folder))
                    : ReadSceneFromFile(request.at("scene_file"), present, PathOf(folder), importOptions);
  BindTexturesToAssets(scene, assets.store, inlineScene != request.end() ? "/scene" : "/scene_file", false);
  std::tie(check.firstFrame, check.lastFrame) = ReadFrameRange(request, scene.render);
  check.width = scene.render.width;
  check.height = scene.render.height;
  check.warnings = ImportWarningsJson(scene.importWarnings);
  return check;
}

JobChange ParseJobChange(const std::string& body) {
  const json request = ParseBody(body);
  const std::string expected = "{\"priority\": " + IntegerRange(kMinPriority, kMaxPriority) +
                               ", \"name\": a string of 1 to " + std::to_string(kMaxChangedNameCharacters) +
                               " characters}, either or both";
  if (!request.is_object()) Fail(error_code::kInvalidField, "", ShowValue(request) + " is not an object", expected);
  constexpr const char* kChangeFields[] = {"priority", "name"};
  CheckKnownFields(request, "", kChangeFields);
  if (request.empty()) Fail(error_code::kMissingField, "", "{} changes nothing", expected);
  JobChange change;
  if (request.contains("priority")) {
    change.priority = ReadInteger(request["priority"], "/priority", kMinPriority, kMaxPriority,
                                  IntegerRange(kMinPriority, kMaxPriority));
  }
  if (request.contains("name")) {
    const json& name = request["name"];
    const std::string nameExpected =
        "a string of 1 to " + std::to_string(kMaxChangedNameCharacters) + " characters";
    if (!name.is_string()) Fail(error_code::kInvalidField, "/name", ShowValue(name) + " is not a string", nameExpected);
    const std::string& text = name.get_ref<const std::string&>();
    // The parser took only valid UTF-8: every byte but a continuation byte starts a character.
    const size_t characters = static_cast<size_t>(
        std::count_if(text.begin(), text.end(), [](char c) { return (static_cast<unsigned char>(c) & 0xC0) != 0x80; }));
    if (characters == 0 || characters > kMaxChangedNameCharacters) {
      Fail(error_code::kInvalidField, "/name",
           characters == 0 ? "the name is empty" : "the name has " + std::to_string(characters) + " characters",
           nameExpected);
    }
    change.name = text;
  }
  return change;
}

std::vector<std::string> ParseMissingAssetsQuery(const std::string& body) {
  const json request = ParseBody(body);
  const std::string expected = "{\"hashes\": [SHA-256, ...]}";
  if (!request.is_object()) Fail(error_code::kInvalidField, "", ShowValue(request) + " is not an object", expected);
  for (const auto& item : request.items()) {
    if (item.key() != "hashes") {
      Fail(error_code::kUnknownField, "/" + EscapePointerToken(item.key()), "unknown field", "only the field hashes");
    }
  }
  const auto hashes = request.find("hashes");
  if (hashes == request.end()) Fail(error_code::kMissingField, "/hashes", "missing", expected);
  if (!hashes->is_array()) {
    Fail(error_code::kInvalidField, "/hashes", ShowValue(*hashes) + " is not an array", expected);
  }
  if (hashes->size() > kMaxHashesPerQuery) {
    Fail(error_code::kInvalidField, "/hashes", std::to_string(hashes->size()) + " hashes are too many",
         "at most " + std::to_string(kMaxHashesPerQuery) + " in one question");
  }
  std::vector<std::string> result;
  for (size_t i = 0; i < hashes->size(); ++i) {
    const json& hash = (*hashes)[i];
    if (!hash.is_string() || !IsAssetHash(hash.get_ref<const std::string&>())) {
      Fail(error_code::kInvalidField, "/hashes/" + std::to_string(i), ShowValue(hash) + " is not a SHA-256",
           "64 lowercase hex characters");
    }
    result.push_back(hash.get<std::string>());
  }
  return result;
}

}  // namespace tcfarm::http
