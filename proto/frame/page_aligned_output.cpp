#include "proto/frame/page_aligned_output.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>

#include "proto/frame/frame_io.h"

namespace tcfarm {
namespace {

size_t RoundUpToPage(size_t bytes) {
  return (bytes + kDirectIoAlignment - 1) / kDirectIoAlignment * kDirectIoAlignment;
}

std::string Why(const std::filesystem::path& path, const char* doing, int error) {
  return "cannot write " + path.string() + ": " + doing + ": " + std::strerror(error);
}

// Writes bytes [from, to) of `data` at their own offsets. A direct write that the file
// system refuses (EINVAL: an offset or length it cannot take, as after a short write)
// turns the rest of the file buffered.
void WriteAll(int fd, const uint8_t* data, size_t from, size_t to, const std::filesystem::path& path) {
  while (from < to) {
    const ssize_t written = ::pwrite(fd, data + from, to - from, static_cast<off_t>(from));
    if (written > 0) {
      from += static_cast<size_t>(written);
      continue;
    }
    const int error = written < 0 ? errno : EIO;  // 0 bytes written: no errno to tell
    if (error == EINTR) continue;
    if (error == EINVAL) {
      const int flags = ::fcntl(fd, F_GETFL);
      if (flags >= 0 && (flags & O_DIRECT) && ::fcntl(fd, F_SETFL, flags & ~O_DIRECT) == 0) continue;
    }
    throw FrameIoError(Why(path, "write", error));
  }
}

}  // namespace

PageAlignedOutput::PageAlignedOutput() : IOProxy("", Write) {}

PageAlignedOutput::~PageAlignedOutput() { std::free(data_); }

void PageAlignedOutput::Reset() {
  size_ = 0;
  m_pos = 0;
}

void PageAlignedOutput::Reserve(size_t bytes) {
  // Whole pages: the padding a direct write rounds up to is always there.
  const size_t wanted = RoundUpToPage(bytes);
  if (wanted <= capacity_) return;
  const size_t capacity = std::max(wanted, RoundUpToPage(capacity_ + capacity_ / 2));
  auto* grown = static_cast<uint8_t*>(std::aligned_alloc(kDirectIoAlignment, capacity));
  if (!grown) throw std::bad_alloc();
  if (size_ > 0) std::memcpy(grown, data_, size_);
  std::free(data_);
  data_ = grown;
  capacity_ = capacity;
}

size_t PageAlignedOutput::pwrite(const void* bytes, size_t size, int64_t offset) {
  if (offset < 0) return 0;
  const size_t end = static_cast<size_t>(offset) + size;
  try {
    Reserve(end);
  } catch (const std::bad_alloc&) {
    error("out of memory for an image of " + std::to_string(end) + " bytes");
    return 0;
  }
  // A seek past the end leaves a hole: zeros, as in a file.
  if (static_cast<size_t>(offset) > size_) std::memset(data_ + size_, 0, static_cast<size_t>(offset) - size_);
  std::memcpy(data_ + offset, bytes, size);
  size_ = std::max(size_, end);
  return size;
}

size_t PageAlignedOutput::write(const void* bytes, size_t size) {
  const size_t written = pwrite(bytes, size, m_pos);
  m_pos += static_cast<int64_t>(written);
  return written;
}

size_t PageAlignedOutput::PaddedSize() const { return RoundUpToPage(size_); }

void PageAlignedOutput::ZeroPadding() {
  if (data_) std::memset(data_ + size_, 0, PaddedSize() - size_);
}

void WriteFileAroundCache(const std::filesystem::path& path, PageAlignedOutput& output) {
  constexpr int kCreate = O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC;
  const bool large = output.size() >= kDirectIoMinBytes;
  int fd = ::open(path.c_str(), kCreate | (large ? O_DIRECT : 0), 0666);
  if (fd < 0 && large && errno == EINVAL) fd = ::open(path.c_str(), kCreate, 0666);  // e.g. tmpfs before Linux 6.6
  if (fd < 0) throw FrameIoError(Why(path, "open", errno));
  try {
    const int flags = ::fcntl(fd, F_GETFL);
    const bool direct = flags >= 0 && (flags & O_DIRECT) != 0;
    if (direct) output.ZeroPadding();
    WriteAll(fd, output.data(), 0, direct ? output.PaddedSize() : output.size(), path);
    if (direct && ::ftruncate(fd, static_cast<off_t>(output.size())) != 0) {
      throw FrameIoError(Why(path, "truncate", errno));
    }
  } catch (...) {
    ::close(fd);
    throw;
  }
  if (::close(fd) != 0) throw FrameIoError(Why(path, "close", errno));
}

}  // namespace tcfarm
