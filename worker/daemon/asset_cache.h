// Files a worker fetched from the coordinator by hash (texture images), kept on disk:
//
//   DIR/<sha256>                  one file per asset, whole and verified
//   DIR/.incoming/<sha256>.<pid>  an asset arriving piece by piece
//
// A file appears under its hash only after its bytes hashed to that name, so any worker
// (several on one machine may share DIR) can trust what it finds there. Soft state: an
// asset missing from DIR is simply fetched again.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "proto/wire/content_hash.h"
#include "proto/wire/wire.h"

namespace tcfarm {

class AssetCache {
 public:
  // Creates dir (owner-only) when missing. Throws std::runtime_error when it cannot.
  AssetCache(std::filesystem::path dir, uint64_t maxAssetBytes);
  ~AssetCache();

  const std::filesystem::path& dir() const { return dir_; }
  uint64_t maxAssetBytes() const { return maxAssetBytes_; }
  // The asset's file, when the cache has it. Safe from any thread.
  std::optional<std::filesystem::path> Find(const std::string& hash) const;

  // Pieces of an asset are accepted only after Expect, and in order.
  void Expect(const std::string& hash);
  bool IsExpected(const std::string& hash) const { return downloads_.count(hash) > 0; }

  enum class Outcome { kIgnored, kIncomplete, kComplete, kFailed };
  // Takes one piece. kComplete: the asset is whole, verified and in the cache. kFailed:
  // the download is dropped and *problem says why (a gap, a size beyond the limit, bytes
  // that do not hash to the name, a disk that refuses them). kIgnored: not expected.
  Outcome Accept(const wire::AssetPiece& piece, std::string* problem);
  // Drops a download (the coordinator cannot serve it), or every one under way (the
  // connection they came on is gone).
  void AbandonDownload(const std::string& hash) { downloads_.erase(hash); }
  void AbandonDownloads() { downloads_.clear(); }

 private:
  struct Download {
    ~Download();
    std::filesystem::path tempPath;
    std::FILE* file = nullptr;
    wire::Sha256Stream hash;
    uint64_t received = 0;
  };
  Outcome Fail(const std::string& hash, const std::string& why, std::string* problem);

  std::filesystem::path dir_;
  uint64_t maxAssetBytes_;
  std::map<std::string, std::unique_ptr<Download>> downloads_;
};

}  // namespace tcfarm
