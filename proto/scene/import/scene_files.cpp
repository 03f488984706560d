#include "proto/scene/import/scene_files.h"

#include <fstream>
#include <sstream>
#include <system_error>

#include "proto/scene/import/messages.h"

namespace tcfarm {

std::filesystem::path ResolveInsideFolder(const std::filesystem::path& folder, const std::string& name,
                                          const std::string& pointer, const std::string& what) {
  const std::string expected = "a relative path that stays inside the scene folder";
  std::filesystem::path relative(name);
  if (name.empty() || relative.has_root_name() || relative.has_root_directory()) {
    FailInput(pointer, what + " " + QuoteInput(name) + " is empty or absolute", expected);
  }
  std::error_code error;
  std::filesystem::path base = std::filesystem::weakly_canonical(folder, error);
  std::filesystem::path resolved;
  if (!error) resolved = std::filesystem::weakly_canonical(folder / relative, error);
  if (error) FailInput(pointer, "cannot resolve " + what + " " + QuoteInput(name) + ": " + error.message(), expected);
  std::filesystem::path inside = resolved.lexically_relative(base);
  if (inside.empty() || inside == "." || *inside.begin() == "..") {
    FailInput(pointer, what + " " + QuoteInput(name) + " resolves outside the scene folder", expected);
  }
  return resolved;
}

std::string ReadSceneFile(const std::filesystem::path& path, const std::string& name, const std::string& pointer,
                          const std::string& what, const std::string& expected) {
  std::ifstream in(path, std::ios::binary);
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error) || !in) {
    FailInput(pointer, "cannot read " + what + " " + QuoteInput(name), expected);
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) FailInput(pointer, "read error in " + what + " " + QuoteInput(name), expected);
  return text.str();
}

}  // namespace tcfarm
