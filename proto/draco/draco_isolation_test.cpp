// Draco stays behind tcfarm_draco_decode and tcfarm_draco_encode: this test links both before
// the importer (the order in which Debian's libdraco.so would put its own tinygltf and stb in
// place of the importer's), and checks that the process still finds tinygltf and stb in their
// own libraries, loads no libdraco.so, and imports a Draco file as its plain twin.
#include <dlfcn.h>
#include <link.h>

#include <gtest/gtest.h>

#include <string>

#include "proto/scene/import/scene_import.h"
#include "tests/support/cpp/compressed_gltf.h"

namespace tcfarm {
namespace {

// The file of the loaded object that defines `symbol` for the whole process ("" when none).
std::string DefiningObject(const char* symbol) {
  void* address = dlsym(RTLD_DEFAULT, symbol);
  Dl_info info{};
  if (address == nullptr || dladdr(address, &info) == 0 || info.dli_fname == nullptr) return "";
  return info.dli_fname;
}

struct Search {
  std::string name;
  bool found = false;
};

bool LoadedObjectNamed(const std::string& name) {
  Search search{name};
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void* data) {
        Search& search = *static_cast<Search*>(data);
        if (info->dlpi_name != nullptr && std::string(info->dlpi_name).find(search.name) != std::string::npos) {
          search.found = true;
        }
        return 0;
      },
      &search);
  return search.found;
}

TEST(DracoIsolationTest, TinygltfAndStbResolveToTheirOwnLibraries) {
  const char* loadAscii =
      "_ZN8tinygltf8TinyGLTF19LoadASCIIFromStringEPNS_5ModelEPNSt7__cxx1112basic_stringIcSt11char_"
      "traitsIcESaIcEEES9_PKcjRKS8_j";
  EXPECT_NE(DefiningObject(loadAscii).find("libtinygltf.so"), std::string::npos) << DefiningObject(loadAscii);
  EXPECT_NE(DefiningObject("stbi_load_from_memory").find("libstb.so"), std::string::npos)
      << DefiningObject("stbi_load_from_memory");
}

TEST(DracoIsolationTest, NoProcessLoadsDebiansLibdraco) {
  EXPECT_FALSE(LoadedObjectNamed("libdraco.so"));
  EXPECT_TRUE(LoadedObjectNamed("libtcfarm_draco_decode.so"));
}

TEST(DracoIsolationTest, DracoImportsAsThePlainFileWhateverTheLinkOrder) {
  const compressed_gltf::Sphere sphere = compressed_gltf::MakeSphere(8, 16);
  EXPECT_EQ(SerializeScene(ImportSceneBytes(compressed_gltf::DracoGltf(sphere).dump(), "gltf")),
            SerializeScene(ImportSceneBytes(compressed_gltf::PlainGltf(sphere).dump(), "gltf")));
}

}  // namespace
}  // namespace tcfarm
