// The shared corpus of tests/scene_files (cases.json): which files each scene references,
// as the importers see it. The Python client (tests/cli/test_scene_files_corpus.py) and the
// dashboard's submit.js (tests/scene_files/submit_js.test.mjs) are held to the same list, so
// a client uploads exactly what the coordinator will read.
//
// A case's files are laid out alone in a fresh folder: the scene imports with them, and
// fails without any one of them; a rejected case fails even with every file of its folder.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/import/scene_import.h"
#include "proto/scene/scene.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kCorpus = fs::path(TCFARM_SOURCE_DIR) / "tests" / "scene_files";

json Cases() {
  std::ifstream in(kCorpus / "cases.json");
  return json::parse(in);
}

class Staging {
 public:
  Staging() : folder_(fs::temp_directory_path() / ("tcfarm-scene-files-" + std::to_string(::getpid()))) {
    fs::remove_all(folder_);
  }
  ~Staging() { fs::remove_all(folder_); }

  // `files` (relative to the case folder) copied into an emptied staging folder.
  void LayOut(const fs::path& caseFolder, const std::vector<fs::path>& files) {
    fs::remove_all(folder_);
    for (const fs::path& file : files) {
      fs::create_directories((folder_ / file).parent_path());
      fs::copy_file(caseFolder / file, folder_ / file);
    }
  }
  // Whether the scene imports; `error` gets the message when it does not.
  bool Imports(const fs::path& scene, std::string* error) const {
    try {
      ImportScene(folder_ / scene);
      return true;
    } catch (const SceneError& e) {
      *error = e.what();
      return false;
    }
  }

 private:
  fs::path folder_;
};

// Every file under `folder`, relative to it.
std::vector<fs::path> AllFiles(const fs::path& folder) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    if (entry.is_regular_file()) files.push_back(entry.path().lexically_relative(folder));
  }
  return files;
}

TEST(SceneFilesCorpusTest, EachSceneReadsExactlyItsListedFiles) {
  const json cases = Cases();
  ASSERT_GE(cases.size(), 5u);
  Staging staging;
  for (const json& entry : cases) {
    SCOPED_TRACE(entry["name"].get<std::string>());
    const fs::path caseFolder = kCorpus / entry["name"].get<std::string>();
    const fs::path scene = entry["scene"].get<std::string>();
    std::string error;
    if (entry.value("rejected", false)) {
      staging.LayOut(caseFolder, AllFiles(caseFolder));
      EXPECT_FALSE(staging.Imports(scene, &error));
      continue;
    }
    // The listed files are relative to the scene's folder.
    std::vector<fs::path> files;
    for (const json& file : entry["files"]) files.push_back(scene.parent_path() / file.get<std::string>());
    staging.LayOut(caseFolder, files);
    EXPECT_TRUE(staging.Imports(scene, &error)) << error;
    for (size_t left = 0; left < files.size(); ++left) {
      if (files[left] == scene) continue;
      std::vector<fs::path> without = files;
      without.erase(without.begin() + static_cast<std::ptrdiff_t>(left));
      staging.LayOut(caseFolder, without);
      EXPECT_FALSE(staging.Imports(scene, &error)) << "imports without " << files[left];
    }
  }
}

}  // namespace
}  // namespace tcfarm
