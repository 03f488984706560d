#include "coordinator/http/asset_routes.h"

#include <httplib.h>
#include <prometheus/registry.h>

#include <memory>
#include <optional>
#include <stdexcept>
#include <string_view>

#include "coordinator/http/submit_request.h"
#include "proto/metrics/metric_builders.h"

namespace tcfarm::http {

using nlohmann::json;

ApiError AssetTooLarge(uint64_t maxBytes) {
  return ApiError(413, error_code::kPayloadTooLarge,
                  "asset is larger than the limit of " + std::to_string(maxBytes) + " bytes (" +
                      std::to_string(maxBytes >> 20) + " MiB, --asset-max-file-mib)");
}

AssetRoutes::AssetRoutes(AssetStore& assets, uint64_t maxFileBytes, prometheus::Registry* metrics)
    : assets_(assets), maxFileBytes_(maxFileBytes) {
  if (metrics == nullptr) return;
  uploads_ = &NewCounter(*metrics, "tcfarm_asset_uploads_total",
                         "Asset uploads accepted (hash verified), whether the store had the asset or not.");
  uploadBytes_ = &NewCounter(*metrics, "tcfarm_asset_upload_bytes_total", "Bytes of the asset uploads accepted.");
}

std::vector<Route> AssetRoutes::Routes() {
  return {
      {"PUT", "/api/v1/assets/([^/]+)", Access::kSubmit, nullptr, Bind(this, &AssetRoutes::PutAsset)},
      {"POST", "/api/v1/assets/missing", Access::kSubmit, Bind(this, &AssetRoutes::FindMissingAssets)},
  };
}

// The body streams to a temp file, hashed on the way; the asset is stored only when the
// hash is the one in the path. The body is read to its end even when the answer is known
// before (a bad hash), so that the connection stays usable; past the size limit it is not.
void AssetRoutes::PutAsset(const httplib::Request& request, const BodyPieces& read, httplib::Response& response) {
  const std::string hash = request.matches[1];
  const bool validHash = IsAssetHash(hash);
  std::unique_ptr<AssetStore::Upload> upload;
  std::optional<std::string> writeError;
  if (validHash) {
    try {
      upload = assets_.BeginUpload();
    } catch (const std::runtime_error& error) {
      writeError = error.what();  // answered once the body is read
    }
  }
  uint64_t received = 0;
  bool tooLarge = false;
  const bool complete = !read || read([&](const char* data, size_t length) {
    received += length;
    if (received > maxFileBytes_) {
      tooLarge = true;
      upload.reset();
    }
    if (!upload) return;
    try {
      upload->Write(std::string_view(data, length));
    } catch (const std::runtime_error& error) {
      writeError = error.what();
      upload.reset();
    }
  });
  // 413 here: the library refused a Content-Length over its limit before reading anything.
  if (tooLarge || response.status == 413) throw AssetTooLarge(maxFileBytes_);
  if (!complete) throw ApiError(400, error_code::kBadRequest, "the request body could not be read");
  if (!validHash) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "asset " + ShowValue(hash) + " is not a SHA-256; expected 64 lowercase hex characters");
  }
  if (writeError) {
    throw ApiError(507, error_code::kInsufficientStorage, "the store could not take the asset: " + *writeError);
  }
  std::string actual;
  AssetStore::CommitResult result = AssetStore::CommitResult::kHashMismatch;
  try {
    result = assets_.Commit(*upload, hash, &actual);
  } catch (const std::runtime_error& error) {
    throw ApiError(507, error_code::kInsufficientStorage,
                   std::string("the store could not take the asset: ") + error.what());
  }
  if (result == AssetStore::CommitResult::kHashMismatch) {
    throw ApiError(400, error_code::kAssetHashMismatch,
                   "the body's SHA-256 is " + actual + ", not " + hash +
                       "; expected the bytes whose SHA-256 the path names");
  }
  if (uploads_ != nullptr) {
    uploads_->Increment();
    uploadBytes_->Increment(static_cast<double>(received));
  }
  WriteJson(response, json{{"sha256", hash}, {"size", received}},
            result == AssetStore::CommitResult::kCreated ? 201 : 200);
}

void AssetRoutes::FindMissingAssets(const httplib::Request&, const std::string& body, httplib::Response& response) {
  const std::vector<std::string> hashes = ParseMissingAssetsQuery(body);
  // What the client will not send again it will name soon: its grace period starts now,
  // so the janitor keeps it for the submission (store_janitor.h, orphan assets).
  assets_.Freshen(hashes);
  WriteJson(response, json{{"missing", assets_.Missing(hashes)}});
}

}  // namespace tcfarm::http
