// POST /api/v1/jobs: the request body, checked field by field, turned into a JobSpec.
#pragma once

#include <string>

#include "http/job_json.h"
#include "jobs/job_store.h"

namespace tcfarm::http {

// Field ranges. bin_width 1 would make every frame its own bin: the search strategy then
// has no neighbouring frame to copy from, which "brute" already says more plainly.
inline constexpr int kMinBinWidth = 2;
inline constexpr int kMaxBinWidth = 1000;
inline constexpr int kMinPriority = -100;
inline constexpr int kMaxPriority = 100;
inline constexpr size_t kMaxNameBytes = 256;  // a label for lists, not a document

// Throws ApiError (status 400) naming the JSON pointer of the first bad value: invalid_json,
// unknown_field, missing_field, invalid_field or invalid_scene. Duplicate keys anywhere in
// the body are refused as invalid_json, as the scene parser refuses them in scene files:
// silently keeping one of two values is never what the sender meant.
// The spec's sceneJson is canonical (SerializeScene), sceneHash its SHA-256; frameSize and
// cameraOrLightsChange come from the scene parsed here, the only parse on the job's way
// to the planners.
JobSpec ParseSubmission(const std::string& body);

}  // namespace tcfarm::http
