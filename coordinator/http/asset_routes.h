// The HTTP API's assets: the files a scene names (textures, meshes), stored by SHA-256.
//   PUT  /api/v1/assets/{sha256}   upload, streamed to disk and hashed on the way
//   POST /api/v1/assets/missing    which of these hashes the store lacks
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "coordinator/http/api_route.h"
#include "coordinator/store/asset_store.h"

namespace tcfarm::http {

// The 413 for an asset over maxBytes (--asset-max-file-mib); the server answers it too
// when its gate refuses an upload's Content-Length before the route runs.
ApiError AssetTooLarge(uint64_t maxBytes);

class AssetRoutes {
 public:
  // maxFileBytes: the largest asset one upload may hold. metrics (may be null) gets the
  // uploads' counts.
  AssetRoutes(AssetStore& assets, uint64_t maxFileBytes, prometheus::Registry* metrics);

  std::vector<Route> Routes();

 private:
  void PutAsset(const httplib::Request& request, const BodyPieces& read, httplib::Response& response);
  void FindMissingAssets(const httplib::Request& request, const std::string& body, httplib::Response& response);

  AssetStore& assets_;
  uint64_t maxFileBytes_;
  prometheus::Counter* uploads_ = nullptr;  // with a metrics registry only
  prometheus::Counter* uploadBytes_ = nullptr;
};

}  // namespace tcfarm::http
