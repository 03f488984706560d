// The files scenes reference (OBJ/MTL, glTF buffers, textures), stored by content:
//
//   STORE/assets/<sha256>              one file per distinct content, never changed
//   STORE/assets/.incoming/            uploads being written (temp file, then rename)
//   STORE/assets/.submissions/<n>/     a submission's files laid out under the paths its
//                                      scene names, while the scene is parsed
//
// A name is the SHA-256 of the bytes, so an asset uploaded once serves every later job,
// and a client asks which hashes are missing before it sends anything. Files appear under
// their name only whole and verified: written to .incoming, hashed as they are written,
// renamed into place only when the hash is the one the uploader named.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "proto/wire/content_hash.h"

namespace tcfarm {

// Limits on the paths a submission gives its assets: long enough for any real project
// tree, short enough that no file system refuses them.
inline constexpr size_t kMaxAssetPathBytes = 1024;
inline constexpr size_t kMaxAssetPathComponentBytes = 255;

// True for 64 lowercase hex characters, the only names the store has.
bool IsAssetHash(std::string_view text);

// Why `path` cannot name an asset in a submission's folder, or nullopt when it can: it must
// be relative, in canonical form ("a/b.obj": no "", "." or ".." component, so it cannot
// escape the folder or name one file twice), '/'-separated, with no NUL or other control
// byte and no backslash, at most kMaxAssetPathBytes long.
std::optional<std::string> AssetPathProblem(std::string_view path);

class AssetStore {
 public:
  // root: STORE/assets; created when missing.
  explicit AssetStore(std::filesystem::path root);

  const std::filesystem::path& root() const { return root_; }
  // Where the asset named hash lies (whether or not it is there yet). hash must be a hash.
  std::filesystem::path PathOf(const std::string& hash) const;
  bool Has(const std::string& hash) const;
  // The asset's size in bytes; nullopt when the store does not have it.
  std::optional<uint64_t> SizeOf(const std::string& hash) const;
  // Up to maxBytes of the asset from offset (fewer at its end). Throws std::runtime_error
  // naming the asset when it cannot be read.
  std::string ReadPiece(const std::string& hash, uint64_t offset, size_t maxBytes) const;
  // The hashes of `hashes` the store does not have, in their order, each once.
  std::vector<std::string> Missing(const std::vector<std::string>& hashes) const;

  // An asset's age is its file's modification time: when it was uploaded, or last
  // freshened. The janitor removes those no job names once they are old
  // (store_janitor.h); a client about to name them freshens them first.
  // The assets last touched before bornBeforeMs (unix milliseconds), by name.
  std::vector<std::string> OlderThan(int64_t bornBeforeMs) const;
  bool OlderThan(int64_t bornBeforeMs, const std::string& hash) const;
  // Those of `hashes` the store has are made young again; the others are ignored.
  void Freshen(const std::vector<std::string>& hashes) const;

  // One upload: bytes streamed to a temp file in .incoming and hashed on the way. The temp
  // file is removed unless Commit moved it into place.
  class Upload {
   public:
    ~Upload();
    Upload(const Upload&) = delete;
    Upload& operator=(const Upload&) = delete;

    // Throws std::runtime_error naming the file when the disk refuses the bytes.
    void Write(std::string_view bytes);
    uint64_t size() const { return size_; }

   private:
    friend class AssetStore;
    explicit Upload(std::filesystem::path tempPath);
    std::filesystem::path tempPath_;
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> file_;
    wire::Sha256Stream hash_;
    uint64_t size_ = 0;
  };
  enum class CommitResult { kCreated, kAlreadyThere, kHashMismatch };
  std::unique_ptr<Upload> BeginUpload();
  // Ends the upload: the asset becomes `expectedHash` when its bytes hash to that; a store
  // that has it already keeps its file. *actualHash (when given) gets the bytes' hash.
  CommitResult Commit(Upload& upload, const std::string& expectedHash, std::string* actualHash = nullptr);
  // The whole of an upload in one call (tests, small files).
  CommitResult Put(const std::string& expectedHash, std::string_view bytes);

  // A submission's files laid out under the paths its scene names: hard links to the
  // stored assets (copies where the file system has no hard links). The folder goes away
  // with this object: the parsed scene holds what it needs inline.
  class Folder {
   public:
    ~Folder();
    Folder(const Folder&) = delete;
    Folder& operator=(const Folder&) = delete;
    const std::filesystem::path& path() const { return path_; }

   private:
    friend class AssetStore;
    explicit Folder(std::filesystem::path path) : path_(std::move(path)) {}
    std::filesystem::path path_;
  };
  // Removes what a coordinator that stopped abruptly left: half-written uploads and
  // submission folders. Only for a store no running coordinator uses; the assets stay.
  void RemoveLeftovers();

  // files: path (checked by AssetPathProblem) -> hash of an asset the store has. Throws
  // std::invalid_argument for a bad path, a path that is both a file and a folder, or a
  // hash the store does not have (the caller checks those first to name them better),
  // std::runtime_error when the disk fails; nothing is left behind either way.
  std::unique_ptr<Folder> Materialise(const std::map<std::string, std::string>& files);

 private:
  std::filesystem::path root_;
};

}  // namespace tcfarm
