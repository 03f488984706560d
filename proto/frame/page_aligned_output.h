// Files written around the page cache. A frame the coordinator stores while a job renders
// is megabytes of floats it will not read again soon; copying them into the page cache
// cost more CPU than encoding them (on a virtual machine, 1.2 s of kernel time for 480 MB
// buffered against 0.04 s direct), and that CPU is taken from the workers tracing on the
// same cores. So an image is encoded into a page-aligned buffer in memory and written with
// O_DIRECT where the file system allows it, buffered where it does not.
#pragma once

#include <OpenImageIO/filesystem.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>

namespace tcfarm {

// An OIIO output proxy over a page-aligned, growing buffer. It keeps its capacity between
// images, so a thread that writes frame after frame pays for its pages once.
class PageAlignedOutput : public OIIO::Filesystem::IOProxy {
 public:
  PageAlignedOutput();
  ~PageAlignedOutput() override;
  PageAlignedOutput(const PageAlignedOutput&) = delete;
  PageAlignedOutput& operator=(const PageAlignedOutput&) = delete;
  const char* proxytype() const override { return "page-aligned"; }
  // Both return 0 when memory runs out, as a full disk would: encoders call them from C
  // (libpng), where an exception must not unwind.
  size_t write(const void* bytes, size_t size) override;
  size_t pwrite(const void* bytes, size_t size, int64_t offset) override;
  size_t size() const override { return size_; }

  // Empties the buffer (keeping its pages) for the next image.
  void Reset();
  const uint8_t* data() const { return data_; }
  // The size rounded up to a whole page, what a direct write writes; ZeroPadding clears
  // the bytes between, so no stale ones reach the disk before the file is truncated.
  size_t PaddedSize() const;
  void ZeroPadding();

 private:
  void Reserve(size_t bytes);

  uint8_t* data_ = nullptr;
  size_t size_ = 0, capacity_ = 0;
};

// Writes `output`'s bytes as the file `path` (created or truncated), bypassing the page
// cache when the file is large enough to gain from it and the file system supports it.
// Throws FrameIoError on failure, naming the path.
void WriteFileAroundCache(const std::filesystem::path& path, PageAlignedOutput& output);

// Page size used for alignment.
constexpr size_t kDirectIoAlignment = 4096;
// Smaller files (masks, previews: kilobytes) are written buffered: a direct write waits
// for the device, and the page cache is cheap at that size.
constexpr size_t kDirectIoMinBytes = size_t{1} << 20;

}  // namespace tcfarm
