#include "worker/daemon/asset_cache.h"

#include <unistd.h>

#include <stdexcept>
#include <system_error>

namespace tcfarm {

AssetCache::AssetCache(std::filesystem::path dir, uint64_t maxAssetBytes)
    : dir_(std::move(dir)), maxAssetBytes_(maxAssetBytes) {
  std::error_code error;
  std::filesystem::create_directories(dir_ / ".incoming", error);
  if (error) throw std::runtime_error("cannot create asset cache " + dir_.string() + ": " + error.message());
  // Only this user's processes may put files where workers trust them by name.
  std::filesystem::permissions(dir_, std::filesystem::perms::owner_all, std::filesystem::perm_options::replace, error);
}

AssetCache::~AssetCache() = default;

AssetCache::Download::~Download() {
  if (file) std::fclose(file);
  std::error_code ignored;
  if (!tempPath.empty()) std::filesystem::remove(tempPath, ignored);
}

std::optional<std::filesystem::path> AssetCache::Find(const std::string& hash) const {
  if (!wire::IsSha256Hex(hash)) return std::nullopt;
  std::filesystem::path path = dir_ / hash;
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) return std::nullopt;
  return path;
}

void AssetCache::Expect(const std::string& hash) {
  if (downloads_.count(hash)) return;
  downloads_[hash] = std::make_unique<Download>();
}

AssetCache::Outcome AssetCache::Fail(const std::string& hash, const std::string& why, std::string* problem) {
  if (problem) *problem = "asset " + hash + ": " + why;
  downloads_.erase(hash);
  return Outcome::kFailed;
}

AssetCache::Outcome AssetCache::Accept(const wire::AssetPiece& piece, std::string* problem) {
  auto found = downloads_.find(piece.assetHash);
  if (found == downloads_.end()) return Outcome::kIgnored;
  Download& download = *found->second;
  if (piece.totalSize > maxAssetBytes_) {
    return Fail(piece.assetHash,
                std::to_string(piece.totalSize) + " bytes is more than this worker's limit of " +
                    std::to_string(maxAssetBytes_) + " (tcfarm-worker serve --asset-max-mib)",
                problem);
  }
  // Pieces of a download this worker dropped and asked for again may still be on their
  // way: until the new one's first piece (offset 0) they are not this download's.
  if (!download.file && piece.offset != 0) return Outcome::kIgnored;
  if (piece.offset != download.received) {
    return Fail(piece.assetHash,
                "a piece at byte " + std::to_string(piece.offset) + " where byte " +
                    std::to_string(download.received) + " was due",
                problem);
  }
  if (!download.file) {
    download.tempPath = dir_ / ".incoming" / (piece.assetHash + "." + std::to_string(getpid()));
    download.file = std::fopen(download.tempPath.c_str(), "wb");
    if (!download.file) return Fail(piece.assetHash, "cannot write " + download.tempPath.string(), problem);
  }
  if (!piece.bytes.empty() && std::fwrite(piece.bytes.data(), 1, piece.bytes.size(), download.file) != piece.bytes.size()) {
    return Fail(piece.assetHash, "the disk refused its bytes at " + download.tempPath.string(), problem);
  }
  download.hash.Update(piece.bytes);
  download.received += piece.bytes.size();
  if (!piece.IsLast()) return Outcome::kIncomplete;

  const bool flushed = std::fclose(download.file) == 0;
  download.file = nullptr;
  if (!flushed) return Fail(piece.assetHash, "the disk refused its bytes at " + download.tempPath.string(), problem);
  const std::string actual = download.hash.Hex();
  if (actual != piece.assetHash) return Fail(piece.assetHash, "its bytes hash to " + actual, problem);
  std::error_code error;
  std::filesystem::rename(download.tempPath, dir_ / piece.assetHash, error);
  if (error) return Fail(piece.assetHash, "cannot move it into the cache: " + error.message(), problem);
  download.tempPath.clear();
  downloads_.erase(found);
  return Outcome::kComplete;
}

}  // namespace tcfarm
