// The JSON request bodies of the API, checked field by field: POST /api/v1/jobs turned into a
// JobSpec, PATCH /api/v1/jobs/{id} into a JobChange, POST /api/v1/assets/missing into the
// hashes it asks about.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "coordinator/http/job_json.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/store/asset_store.h"

namespace tcfarm::http {

// Field ranges. bin_width 1 would make every frame its own bin: the search strategy then
// has no neighbouring frame to copy from, which "brute" already says more plainly.
inline constexpr int kMinBinWidth = 2;
inline constexpr int kMaxBinWidth = 1000;
inline constexpr int kMinPriority = JobStore::kMinPriority;
inline constexpr int kMaxPriority = JobStore::kMaxPriority;
inline constexpr size_t kMaxNameBytes = 256;  // a label for lists, not a document
// A name given afterwards (PATCH), counted in characters (Unicode code points).
inline constexpr size_t kMaxChangedNameCharacters = 200;
// A scene with more files than this is a project tree, not a shot; it also bounds the
// folder a submission lays out.
inline constexpr size_t kMaxAssetsPerJob = 10000;
// One missing-assets question: a large project's assets, each answered by one stat.
inline constexpr size_t kMaxHashesPerQuery = 100000;

// Where a submission's "assets" come from. Without a store, a submission naming assets
// is refused, as a scene naming files always was.
struct SubmissionAssets {
  AssetStore* store = nullptr;
  uint64_t maxJobBytes = 0;  // the assets' total size a job may have; 0: no limit
  std::string maxJobFlag;    // how messages name that limit ("--asset-max-job-mib")
};

// Throws ApiError (status 400) naming the JSON pointer of the first bad value: invalid_json,
// unknown_field, missing_field, invalid_field or invalid_scene. Duplicate keys anywhere in
// the body are refused as invalid_json, as the scene parser refuses them in scene files:
// silently keeping one of two values is never what the sender meant.
// The spec's sceneJson is canonical (SerializeScene), sceneHash its SHA-256; frameSize and
// cameraOrLightsChange come from the scene parsed here, the only parse on the job's way
// to the planners.
//
// "assets" ({relative path: sha256}) are laid out in a folder of the asset store while the
// scene is parsed, so mesh "file" references and a "scene_file" (any format ImportScene
// reads) resolve there; the folder is gone when this returns, since the parsed scene holds
// its meshes inline. Asset errors: a bad path or hash is invalid_field and a hash the store
// lacks missing_asset, both at /assets/<path>; a total past maxJobBytes is 413
// job_too_large at /assets.
JobSpec ParseSubmission(const std::string& body, const SubmissionAssets& assets = {});

// POST /api/v1/scenes/check: what the submission of this body would import, and nothing
// stored. The body is a submission's, plus "scene_file_data" (the scene file's bytes in
// base64, named by "scene_file", for a check before it is uploaded; it need not be among
// the assets). When every asset named is in the store the scene is imported as the submit
// imports it and refused with the same 400s. When some are not yet uploaded
// (missingAssets), the job's fields are checked and the scene file alone
// (CheckSceneFileAlone): what it names is checked once the submission brings it.
struct SceneCheck {
  bool complete = true;
  std::vector<std::string> missingAssets;  // paths of "assets" whose hash the store lacks
  // The import's result, when complete.
  int firstFrame = 0, lastFrame = 0, width = 0, height = 0;
  nlohmann::json warnings = nlohmann::json::array();  // Scene::importWarnings, as the job record has them
};
SceneCheck CheckSubmission(const std::string& body, const SubmissionAssets& assets);

// PATCH /api/v1/jobs/{id}: {"priority": int in [-100, 100], "name": 1 to 200 characters},
// either or both. Throws ApiError 400 (invalid_json, unknown_field, missing_field for {},
// invalid_field) naming the pointer of the first bad value.
JobChange ParseJobChange(const std::string& body);

// POST /api/v1/assets/missing: {"hashes": [sha256, ...]}. Throws ApiError 400 (invalid_json,
// unknown_field, missing_field, invalid_field) naming the pointer of the first bad value.
std::vector<std::string> ParseMissingAssetsQuery(const std::string& body);

}  // namespace tcfarm::http
