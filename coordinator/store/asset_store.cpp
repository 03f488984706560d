#include "coordinator/store/asset_store.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>
#include <stdexcept>
#include <system_error>

#include <fcntl.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

constexpr const char* kIncoming = ".incoming";
constexpr const char* kSubmissions = ".submissions";

std::string SystemMessage(int error) { return std::generic_category().message(error); }

// mkstemp/mkdtemp: unique names made by the kernel, so two uploads (or two coordinators
// on one store) never share a temp file.
std::string Template(const fs::path& folder, const char* stem) { return (folder / stem).string() + "XXXXXX"; }

}  // namespace

bool IsAssetHash(std::string_view text) { return wire::IsSha256Hex(text); }

std::optional<std::string> AssetPathProblem(std::string_view path) {
  if (path.empty()) return "the path is empty";
  if (path.size() > kMaxAssetPathBytes) {
    return "the path is " + std::to_string(path.size()) + " bytes long, more than " +
           std::to_string(kMaxAssetPathBytes);
  }
  for (char c : path) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return "the path holds a NUL or control byte";
    if (c == '\\') return "the path holds a backslash";
  }
  if (path.front() == '/') return "the path is absolute";
  size_t begin = 0;
  while (true) {
    const size_t end = path.find('/', begin);
    const std::string_view component = path.substr(begin, end == std::string_view::npos ? end : end - begin);
    if (component.empty()) return "the path has an empty component";
    if (component == ".") return "the path has a \".\" component";
    if (component == "..") return "the path has a \"..\" component";
    if (component.size() > kMaxAssetPathComponentBytes) {
      return "a component of the path is longer than " + std::to_string(kMaxAssetPathComponentBytes) + " bytes";
    }
    if (end == std::string_view::npos) return std::nullopt;
    begin = end + 1;
  }
}

AssetStore::AssetStore(fs::path root) : root_(std::move(root)) {}

fs::path AssetStore::PathOf(const std::string& hash) const {
  if (!IsAssetHash(hash)) throw std::invalid_argument("AssetStore: " + hash + " is not a SHA-256 in hex");
  return root_ / hash;
}

bool AssetStore::Has(const std::string& hash) const {
  std::error_code error;
  return fs::is_regular_file(PathOf(hash), error);
}

std::optional<uint64_t> AssetStore::SizeOf(const std::string& hash) const {
  std::error_code error;
  const uintmax_t size = fs::file_size(PathOf(hash), error);
  if (error) return std::nullopt;
  return static_cast<uint64_t>(size);
}

std::string AssetStore::ReadPiece(const std::string& hash, uint64_t offset, size_t maxBytes) const {
  std::ifstream in(PathOf(hash), std::ios::binary);
  if (!in) throw std::runtime_error(hash + ": cannot open it");
  in.seekg(static_cast<std::streamoff>(offset));
  std::string piece(maxBytes, '\0');
  in.read(piece.data(), static_cast<std::streamsize>(maxBytes));
  if (in.bad()) throw std::runtime_error(hash + ": read error");
  piece.resize(static_cast<size_t>(in.gcount()));
  return piece;
}

std::vector<std::string> AssetStore::Missing(const std::vector<std::string>& hashes) const {
  std::vector<std::string> missing;
  std::set<std::string> seen;
  for (const std::string& hash : hashes) {
    if (seen.insert(hash).second && !Has(hash)) missing.push_back(hash);
  }
  return missing;
}

namespace {

// The file's modification time in unix milliseconds; nullopt when it is gone.
std::optional<int64_t> ModifiedMs(const fs::path& path) {
  struct stat status;
  if (::stat(path.c_str(), &status) != 0) return std::nullopt;
  return int64_t{status.st_mtim.tv_sec} * 1000 + status.st_mtim.tv_nsec / 1'000'000;
}

}  // namespace

std::vector<std::string> AssetStore::OlderThan(int64_t bornBeforeMs) const {
  std::vector<std::string> old;
  std::error_code error;
  for (fs::directory_iterator it(root_, error), end; !error && it != end; it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (IsAssetHash(name) && OlderThan(bornBeforeMs, name)) old.push_back(name);
  }
  return old;
}

bool AssetStore::OlderThan(int64_t bornBeforeMs, const std::string& hash) const {
  const std::optional<int64_t> modified = ModifiedMs(PathOf(hash));
  return modified && *modified < bornBeforeMs;
}

void AssetStore::Freshen(const std::vector<std::string>& hashes) const {
  for (const std::string& hash : hashes) {
    // Now, as the file system keeps time; an asset that is gone stays gone.
    if (IsAssetHash(hash)) ::utimensat(AT_FDCWD, PathOf(hash).c_str(), nullptr, 0);
  }
}

// --- uploads -------------------------------------------------------------------------------

AssetStore::Upload::Upload(fs::path tempPath) : tempPath_(std::move(tempPath)), file_(nullptr, &std::fclose) {}

AssetStore::Upload::~Upload() {
  file_.reset();
  std::error_code error;
  if (!tempPath_.empty()) fs::remove(tempPath_, error);
}

void AssetStore::Upload::Write(std::string_view bytes) {
  if (!file_) throw std::logic_error("AssetStore::Upload: Write after Commit");
  if (!bytes.empty() && std::fwrite(bytes.data(), 1, bytes.size(), file_.get()) != bytes.size()) {
    throw std::runtime_error("cannot write asset upload " + tempPath_.string() + ": " + SystemMessage(errno));
  }
  hash_.Update(bytes);
  size_ += bytes.size();
}

std::unique_ptr<AssetStore::Upload> AssetStore::BeginUpload() {
  const fs::path incoming = root_ / kIncoming;
  fs::create_directories(incoming);
  std::string name = Template(incoming, "upload-");
  const int descriptor = mkstemp(name.data());
  if (descriptor < 0) {
    throw std::runtime_error("cannot create an upload file in " + incoming.string() + ": " + SystemMessage(errno));
  }
  std::unique_ptr<Upload> upload(new Upload(name));
  upload->file_.reset(fdopen(descriptor, "wb"));
  if (!upload->file_) {
    const int error = errno;
    close(descriptor);
    throw std::runtime_error("cannot open upload file " + name + ": " + SystemMessage(error));
  }
  return upload;
}

AssetStore::CommitResult AssetStore::Commit(Upload& upload, const std::string& expectedHash,
                                            std::string* actualHash) {
  const std::string hash = upload.hash_.Hex();
  if (actualHash != nullptr) *actualHash = hash;
  // Durable before visible: a crash after the rename must not leave a named asset whose
  // bytes never reached the disk.
  std::FILE* file = upload.file_.get();
  const bool written = std::fflush(file) == 0 && fsync(fileno(file)) == 0;
  const int writeError = errno;
  if (std::fclose(upload.file_.release()) != 0 || !written) {
    throw std::runtime_error("cannot write asset upload " + upload.tempPath_.string() + ": " +
                             SystemMessage(written ? errno : writeError));
  }
  if (hash != expectedHash) return CommitResult::kHashMismatch;
  if (Has(hash)) {
    Freshen({hash});  // uploaded again for a submission on its way
    return CommitResult::kAlreadyThere;  // the destructor removes the temp file
  }
  // rename(2) is atomic: readers see the whole file or none. Two uploads of one hash racing
  // here both succeed; their bytes are the same.
  fs::rename(upload.tempPath_, PathOf(hash));
  upload.tempPath_.clear();
  return CommitResult::kCreated;
}

AssetStore::CommitResult AssetStore::Put(const std::string& expectedHash, std::string_view bytes) {
  std::unique_ptr<Upload> upload = BeginUpload();
  upload->Write(bytes);
  return Commit(*upload, expectedHash);
}

void AssetStore::RemoveLeftovers() {
  for (const char* leftovers : {kIncoming, kSubmissions}) {
    std::error_code error;
    fs::remove_all(root_ / leftovers, error);
    if (error) {
      std::fprintf(stderr, "coordinator: cannot remove %s: %s\n", (root_ / leftovers).c_str(), error.message().c_str());
    }
  }
}

// --- a submission's folder -----------------------------------------------------------------

AssetStore::Folder::~Folder() {
  std::error_code error;
  fs::remove_all(path_, error);
  if (error) {
    std::fprintf(stderr, "coordinator: cannot remove submission folder %s: %s\n", path_.c_str(),
                 error.message().c_str());
  }
}

std::unique_ptr<AssetStore::Folder> AssetStore::Materialise(const std::map<std::string, std::string>& files) {
  const fs::path submissions = root_ / kSubmissions;
  fs::create_directories(submissions);
  std::string name = Template(submissions, "");
  if (mkdtemp(name.data()) == nullptr) {
    throw std::runtime_error("cannot create a submission folder in " + submissions.string() + ": " +
                             SystemMessage(errno));
  }
  std::unique_ptr<Folder> folder(new Folder(name));  // removes what is made so far on a throw
  for (const auto& [path, hash] : files) {
    if (std::optional<std::string> problem = AssetPathProblem(path)) {
      throw std::invalid_argument("asset path \"" + path + "\": " + *problem);
    }
    if (!Has(hash)) throw std::invalid_argument("no asset " + hash + " for \"" + path + "\"");
    const fs::path target = folder->path() / fs::path(path);
    std::error_code error;
    fs::create_directories(target.parent_path(), error);
    // A path that is another's folder ("a" and "a/b"): the map's order puts "a" first, so
    // either the folder cannot be made or the file exists where the folder should be.
    if (error || fs::exists(target, error)) {
      throw std::invalid_argument("asset path \"" + path + "\" is both a file and a folder of another path");
    }
    fs::create_hard_link(PathOf(hash), target, error);
    if (error) {
      // Another file system under the store, or the link count at its limit: copy instead.
      error.clear();
      fs::copy_file(PathOf(hash), target, error);
      if (error) {
        throw std::runtime_error("cannot lay out asset " + hash + " as " + target.string() + ": " + error.message());
      }
    }
  }
  return folder;
}

}  // namespace tcfarm
