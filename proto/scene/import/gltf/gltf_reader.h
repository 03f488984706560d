// The glTF reader: a loaded tinygltf model -> Scene, with everything the scene model relies
// on checked and refused with the glTF pointer of the bad value. Its members are defined by
// role: loading.cpp (the container, pre-checks, tinygltf), meshopt_views.cpp and
// draco_primitives.cpp (compressed geometry, decoded into plain buffers), extension_values.cpp,
// accessors.cpp, materials.cpp, animation.cpp (node graph, transforms, animation channels),
// meshes.cpp, skins_morphs.cpp, cameras_lights.cpp.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "proto/scene/import/gltf_data_uris.h"
#include "proto/scene/import/gltf/json_types.h"
#include "proto/scene/import/mesh_geometry.h"
#include "proto/scene/import/importers.h"
#include "proto/scene/scene_limits.h"
#include "proto/scene/import/messages.h"
#include "proto/scene/import/scene_files.h"

namespace tcfarm::draco_codec {
class DecodedMesh;
}  // namespace tcfarm::draco_codec

namespace tcfarm::gltf {

using import::CrossProduct;
using import::HasArea;
using import::Norm;
using import::Normalized;
using import::Sub;

// The scene format's limits (scene_limits.h), checked here so that a glTF file is refused
// with its own pointer rather than the pointer of the JSON it would become.
using scene_limits::kMaxFrameCount;
using scene_limits::kMaxJoints;
using scene_limits::kMaxMagnitude;
using scene_limits::kMaxMotionDepth;
using scene_limits::kMaxScale;
using scene_limits::kMaxTriangles;
using scene_limits::kMinScale;
constexpr double kPi = 3.14159265358979323846;
// The most elements one accessor may hold: the indices of the most triangles a scene may
// hold. Far below 2^31, so that no count can ask for more than a few GiB of values.
constexpr size_t kMaxAccessorCount = 3 * kMaxTriangles;
// The values all accessor reads together may produce (8 bytes each), per byte of the
// file's buffers, plus a fixed allowance: an accessor of bytes read once gives 8 per byte,
// and a short JSON naming one large accessor over and over must not multiply it.
constexpr uint64_t kValueBytesPerBufferByte = 16;
constexpr uint64_t kValueBytesAllowance = uint64_t{16} << 20;
// Decoding compressed geometry may bring more per byte of the file's buffers: Draco with
// quantized attributes compresses a real mesh 20 to 30 times (a 2-million-triangle sphere
// at 14 bits: 60 MB from 2.4 MB), while a run of zeros through meshopt's codec, 64 times,
// stays refused. A file of 1 MiB still decodes to at most 48 MiB.
constexpr uint64_t kDecodedBytesPerBufferByte = 32;
// glTF's defaults for what a file leaves out.
constexpr int kDefaultWidth = 640, kDefaultHeight = 480;
// A matrix whose columns, once divided by their lengths, are further than this from
// orthonormal has shear (or a projective row) that translation, rotation and scale cannot
// express. Exporters write rotations to float precision, hence not tighter.
constexpr double kOrthonormalTolerance = 1e-5;
// A column shorter than this (relative to the longest) makes the matrix singular.
constexpr double kSingularRatio = 1e-12;
// The most vertex deformations framing the animation may spend (frames x deformed vertices);
// past it, evenly spaced frames are framed.
constexpr size_t kFramingVertexBudget = size_t{20} << 20;
using import::kDefaultLightDirection;

// What this importer implements, for extensionsRequired; optional others are ignored.
inline const std::set<std::string> kSupportedExtensions = {
    "KHR_lights_punctual",          "KHR_materials_transmission", "KHR_materials_ior",
    "KHR_mesh_quantization",        "KHR_materials_emissive_strength", "KHR_materials_unlit",
    "KHR_materials_specular",       "KHR_texture_transform",           "KHR_materials_clearcoat",
    "KHR_draco_mesh_compression",   "EXT_meshopt_compression",         "EXT_texture_webp"};

class GltfReader {
 public:
  GltfReader(const ImportInput& input);

  Scene Read();
  // What the file alone shows, without the buffers and images it names (they may not have
  // been uploaded yet): the container, the JSON's syntax and types, required extensions.
  void CheckAlone();

 private:
  [[noreturn]] void Fail(const std::string& pointer, const std::string& problem, const std::string& expected) const;
  // Prints the warning (a render shows it) and keeps it for Scene::importWarnings (a
  // submission's job record shows it). `code` names the kind of warning (ImportWarning).
  void Warn(const std::string& code, const std::string& pointer, const std::string& text) const;

  bool IsBinary() const;

  // The GLB container (header, JSON chunk, optional BIN chunk), checked before tinygltf
  // reads it so that a truncated file is refused with the byte offset where it falls short.
  // Returns the JSON text.
  std::string_view CheckContainer() const;

  // The JSON with its data URIs decoded (embedded_), its nesting checked as an HTTP body's
  // is (kMaxJsonDepth), and the memory reading it takes charged to the import budget:
  // `copiesOfTheFile` times the file's size, and the documents parsed from the JSON.
  void ExtractDocument(uint64_t copiesOfTheFile);

  // What tinygltf reports without saying where: extensions this importer lacks, and
  // files that are missing. Syntax and type errors are left to tinygltf.
  void PreCheck(const std::string& jsonText) const;
  // PreCheck's part that needs no other file: the JSON's syntax (a parse error said where
  // it stops, in the parser's words), the version, the value types, required extensions.
  void CheckDocument(const nlohmann::json& document) const;

  // asset.version: a glTF 1.0 file (whose properties have other shapes) is refused as such,
  // before the type check would call one of its differences a wrong type.
  void CheckVersion(const nlohmann::json& document) const;

  // tinygltf would report a buffer whose data URI decodes to another length than its
  // byteLength under the name that replaced the URI.
  void CheckEmbeddedLength(const nlohmann::json& item, size_t decoded, const std::string& pointer) const;

  // What tinygltf reads: the file with its data URIs replaced by their names. A GLB's
  // JSON chunk is rebuilt only when that or a stand-in changed it.
  std::string GlbWithJson(const std::string& json) const;

  void Load();

  // Refuses a required extension the importer does not implement; warns of a used one.
  void CheckExtensions() const;

  // ---- extension objects (tinygltf keeps them as Values) ---------------------------------

  // The object extension `name` holds, if it is one.
  static const tinygltf::Value* ExtensionOf(const tinygltf::ExtensionMap& extensions, const std::string& name);
  // `key` of an extension object as a whole number (below 2^53): `fallback` when absent, else refused.
  uint64_t WholeNumberIn(const tinygltf::Value& object, const std::string& key, const std::string& pointer,
                         std::optional<uint64_t> fallback = std::nullopt) const;
  std::string StringIn(const tinygltf::Value& object, const std::string& key, const std::string& pointer,
                       const std::string& fallback) const;

  // ---- compressed geometry, decoded into plain buffers -----------------------------------
  // Both decoders write what they decode into buffers of their own appended to the model and
  // point the buffer views (meshopt) or accessors (Draco) there, so that everything after
  // reads plain geometry through ReadAccessor and the scene holds decoded data only.

  // EXT_meshopt_compression's fallback buffers without a uri hold nothing to read; tinygltf
  // would refuse them, so each gets a one-byte stand-in in the JSON it reads. Before PreCheck.
  void StandInForFallbackBuffers();
  // tinygltf refuses indices without a buffer view, which Draco's extension allows: such an
  // accessor reads the Draco buffer view in the JSON tinygltf reads, until the decoded faces
  // replace it. Before PreCheck.
  void StandInForDracoIndexViews();
  // Every buffer view with EXT_meshopt_compression, decoded and filtered (after Load).
  void DecodeMeshoptViews();
  void DecodeMeshoptView(size_t index, const tinygltf::Value& extension);
  // Every primitive with KHR_draco_mesh_compression: its attributes' and indices' accessors
  // then read the decoded mesh (after DecodeMeshoptViews).
  void DecodeDracoPrimitives();
  void DecodeDracoPrimitive(tinygltf::Primitive& primitive, const std::string& pointer);
  // The accessor `index` that decoded Draco data of `count` elements fills: it exists, it is
  // filled once, and its count is the decoded one.
  tinygltf::Accessor& DracoAccessor(int index, size_t count, const std::string& at);
  void WriteDracoAttribute(int index, const draco_codec::DecodedMesh& mesh, uint32_t id, const std::string& at);
  void WriteDracoIndices(int index, const draco_codec::DecodedMesh& mesh, const std::string& at);
  // Points the accessor at `bytes`, in a buffer and buffer view of their own.
  void PointAccessorAt(tinygltf::Accessor& accessor, std::vector<unsigned char> bytes);
  // Appends `bytes` as a buffer of their own; returns its index.
  int AddDecodedBuffer(std::vector<unsigned char> bytes);
  // Decoded bytes count against the value budget of the file's own buffers, so that a small
  // compressed file cannot decode into gigabytes.
  void ChargeDecodedBytes(uint64_t bytes, const std::string& pointer) const;

  // ---- accessors ------------------------------------------------------------------------

  struct AccessorData {
    size_t count = 0;
    int components = 0;
    std::vector<double> values;  // count * components
    double At(size_t element, int component) const { return values[element * components + component]; }
  };

  // Where `count` elements of `elementSize` bytes start in a buffer, and how far apart.
  struct ViewElements {
    const unsigned char* base;
    size_t stride;
  };
  // A sparse accessor's substitutions: `count` indices of `indexType`, and as many values.
  struct SparseLayout {
    size_t count;
    int indexType;
    size_t indexSize;
    ViewElements indices, values;
  };
  // Where an accessor's elements lie: `elements` none when it has no buffer view (all zeros).
  struct AccessorLayout {
    std::optional<ViewElements> elements;
    std::optional<SparseLayout> sparse;
  };

  // An accessor's elements as doubles. `types` are the allowed TINYGLTF_TYPE_*; integer
  // components of a normalized accessor become [0, 1] (or [-1, 1]) as the spec says. A
  // sparse accessor's substitutions are applied over its buffer view's elements (or zeros).
  AccessorData ReadAccessor(int index, const std::string& referencedAt, const std::vector<int>& types,
                            const std::vector<int>& componentTypes, const std::string& expected) const;

  void ChargeValues(uint64_t values, const std::string& pointer) const;
  // The one counter of value bytes (ChargeValues, ChargeDecodedBytes), against a budget of
  // `perBufferByte` per byte of `bufferBytes`, plus kValueBytesAllowance.
  void ChargeValueBytes(uint64_t bytes, uint64_t perBufferByte, size_t bufferBytes, const std::string& doing,
                        const std::string& pointer) const;

  size_t BufferBytes() const;

  // The one gate every read of an accessor passes before anything is allocated per
  // element: its count below the limit, its elements inside its buffer view and the view
  // inside its buffer (or, without a view, no more zeros than the file has buffer bytes),
  // and its sparse substitutions' views likewise. 64-bit arithmetic that cannot overflow.
  AccessorLayout CheckedLayout(const tinygltf::Accessor& accessor, const std::string& pointer,
                               size_t elementSize) const;

  // Where `count` elements of `elementSize` bytes start in buffer view `viewIndex`, from
  // byteOffset, and how far apart they lie (the view's byteStride, when `strided`, else
  // packed): checked to lie inside the view and the view inside its buffer. `pointer` is
  // the object referring to the view (an accessor, or a sparse accessor's indices or values).
  ViewElements InView(int viewIndex, size_t byteOffset, size_t count, size_t elementSize, bool strided,
                      const std::string& pointer) const;

  static void ReadElement(const unsigned char* at, const tinygltf::Accessor& accessor, int componentSize,
                          double* out);

  // A sparse accessor's substitutions: `count` strictly increasing element indices, and as
  // many packed elements of the accessor's own type that replace those elements.
  SparseLayout CheckedSparseLayout(const tinygltf::Accessor& accessor, const std::string& pointer,
                                   size_t elementSize) const;

  void ApplySparse(const tinygltf::Accessor& accessor, const std::string& pointer, int componentSize,
                   const SparseLayout& sparse, AccessorData& data) const;

  static std::string TypeName(int type);

  static std::string ComponentTypeName(int componentType);

  // One component of type T at `at` (glTF is little-endian, as every host this builds on),
  // as its value or, normalized, as glTF maps integers into [-1, 1] or [0, 1].
  template <typename T>
  static double Load(const unsigned char* at, bool normalized) {
    T v;
    std::memcpy(&v, at, sizeof v);
    if (!normalized || !std::is_integral_v<T>) return v;
    const double scaled = v / static_cast<double>(std::numeric_limits<T>::max());
    return std::is_signed_v<T> ? std::max(scaled, -1.0) : scaled;
  }

  static double Component(const unsigned char* at, int componentType, bool normalized);

  void CheckFinite(const AccessorData& data, int index, const std::string& what) const;
  // Integer unit vectors (KHR_mesh_quantization's normals and tangents) are normalized.
  void CheckNormalized(int index, const std::string& what) const;

  // ---- materials ------------------------------------------------------------------------

  static double NumberIn(const tinygltf::ExtensionMap& extensions, const std::string& extension, const std::string& key,
                         double fallback);

  // glTF's metallic-roughness material as it is, with the extensions tcfarm implements
  // (proto/scene.md, "glTF materials").
  Material MapMaterial(const tinygltf::Material& source, size_t index) const;
  void MapExtensions(const tinygltf::Material& source, const std::string& pointer, MetallicRoughness& m) const;
  void MapClearcoat(const tinygltf::Value& extension, const std::string& pointer, MetallicRoughness& m) const;
  // A texture reference inside a material extension's object (tinygltf leaves those as
  // JSON values): none when `key` is absent.
  std::optional<TextureSlot> MapExtensionSlot(const tinygltf::Value& extension, const std::string& key,
                                              const std::string& pointer) const;

  // glTF's sampler codes (WebGL's enums); a sampler that leaves one out means repeat and
  // the renderer's choice of filter, here bilinear.
  static Texture::Wrap WrapOf(int code);

  // The image a texture shows and the pointer of the index naming it: EXT_texture_webp's
  // source when it has one (workers decode WebP), else the texture's own. KHR_texture_basisu's
  // KTX2 images are not decoded: the texture's own source stands in, said; without one the
  // texture is left out (nullopt), said too.
  struct ImageSource {
    int64_t index;
    std::string pointer;
  };
  std::optional<ImageSource> ImageSourceOf(const tinygltf::Texture& texture, const std::string& texturePointer) const;
  // Texture `index` with its image's bytes; nullopt when it is left out (ImageSourceOf).
  std::optional<Texture> MapTexture(int index, const std::string& pointer) const;
  // A material's texture reference (TextureInfo and its normal and occlusion kinds): the
  // texture, its texture coordinates and their KHR_texture_transform.
  std::optional<TextureSlot> MapSlot(int index, int texCoord, const tinygltf::ExtensionMap& extensions,
                                     const std::string& pointer) const;
  static double FactorIn(const tinygltf::Value& object, const std::string& key, double fallback);

  // Materials as the scene parser orders them ("default" first, then by name), so the
  // scene reads back with the same indices. Primitives without a material get the
  // built-in default, not glTF's (a black metal).
  void AddMaterials(Scene& scene);

  // ---- node graph -----------------------------------------------------------------------

  // Parents of every node, and the roots of the scene to render; a node with two parents
  // or on a cycle is refused.
  void BuildGraph();

  // ---- transforms and animation ---------------------------------------------------------

  // A column-major matrix as translation, rotation and scale, or refused.
  void Decompose(const std::vector<double>& m, const std::string& pointer, Vec3* translation, Quaternion* rotation,
                 Vec3* scale) const;

  // The animation to play: by name or index, the first by default; none when the file
  // has none.
  void ChooseAnimation();

  struct Channel {
    bool present = false;
    std::vector<double> times;
    AccessorData values;
    Interpolation interpolation = Interpolation::kLinear;
  };

  // Keyframe frames from a sampler's input: finite, non-negative, strictly increasing.
  std::vector<double> ReadTimes(int accessor, const std::string& referencedAt) const;

  // A sampler's keys: their frames, interpolation and values, `perKey` elements per key
  // (per in-tangent, value and out-tangent for CUBICSPLINE), checked to be as many as that.
  Channel ReadChannel(const tinygltf::AnimationSampler& sampler, const std::string& samplerPointer, int type,
                      const std::vector<int>& componentTypes, const std::string& expected, size_t perKey) const;

  // Node i's local translation, rotation and scale over frames, from the node and the
  // chosen animation's channels; the channels of morph target weights are kept for the
  // shapes.
  void BuildMotions();

  Motion LocalMotion(size_t index, const std::map<std::string, Channel>& channels) const;

  // The scene's frame count: the animation's, or up to the caller's last frame
  // (ImportOptions::lastFrame) when that is past its end, those frames holding the last key.
  int FramesAsked() const;

  // ---- meshes ---------------------------------------------------------------------------

  TriangleMesh PrimitiveMesh(const tinygltf::Primitive& primitive, const std::string& pointer) const;

 public:
  // The triangles of a TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN list, as the glTF spec
  // numbers them (a strip alternates its winding so every triangle faces the same way).
  static std::vector<std::array<uint32_t, 3>> Triangles(const std::vector<uint32_t>& indices, int mode);

 private:
  // How many of the scene's nodes place each mesh.
  std::vector<int> NodesPerMesh() const;

  // The name a shared primitive takes in Scene::meshes: its glTF mesh's name (else
  // `mesh<i>`), `/p` after it when the mesh has several primitives, `#<i>` after a name
  // another mesh has taken already.
  static std::string SharedMeshName(const tinygltf::Mesh& mesh, size_t meshIndex, size_t primitive,
                                    const Scene& scene);

  // Gives the shape the primitive's triangles: its own when one node places the mesh,
  // else the scene's shared copy (read once, in the mesh's space; each node's Motion
  // places it).
  void SetPrimitiveMesh(Shape& shape, size_t meshIndex, size_t p, bool shared, const std::string& pointer,
                        Scene& scene);

  void AddShapes(Scene& scene);
  // A material whose textures read a texture coordinate set the primitive lacks is drawn
  // without those textures: said, not silent.
  void WarnOfMissingTexCoords(const Material& material, const TriangleMesh& mesh, const std::string& pointer) const;

  // ---- skins and morph targets ----------------------------------------------------------

  // How many morph targets node i's mesh has (0 without a mesh): the same in every
  // primitive and as many as the mesh's default weights, or refused.
  size_t MorphTargetCount(size_t node) const;

  // Default weights (a mesh's or a node's): none, or one finite weight per morph target.
  void CheckWeights(const std::vector<double>& weights, size_t targets, const std::string& pointer) const;

  // Node i's morph target weights over frame time: its animation's weights channel, else
  // the node's `weights`, else its mesh's, else zeros.
  AnimatedWeights MorphWeights(size_t node, size_t targets) const;

  // A primitive's morph targets: POSITION and NORMAL deltas, one per vertex (a target
  // without POSITION moves nothing; NORMAL deltas are kept only for a mesh with normals).
  MorphTargets ReadMorphTargets(const tinygltf::Primitive& primitive, const std::string& pointer,
                                const TriangleMesh& mesh) const;

  // What a skin gives every primitive it binds: its joints' world motions and inverse
  // bind matrices, read and checked once.
  struct SkinJoints {
    std::vector<Motion> joints;
    std::vector<Affine> inverseBind;
  };

  const SkinJoints& ReadSkin(size_t node);

  static std::string Row(double a, double b, double c, double d);

  // COLOR_0: linear RGB (an alpha is not used), FLOAT or normalized UNSIGNED_BYTE or
  // UNSIGNED_SHORT, one per position.
  std::vector<Vec3> ReadVertexColors(int index, const std::string& referencedAt, size_t positions) const;
  std::vector<std::array<double, 2>> ReadTexCoords(const tinygltf::Primitive& primitive, const std::string& attribute,
                                                   const std::string& pointer, size_t positions) const;
  std::vector<std::array<double, 4>> ReadTangents(int index, const std::string& pointer, size_t positions) const;

  // A primitive's skin: JOINTS_0/WEIGHTS_0 (and _1 for 8 influences), each vertex's weights
  // divided by their sum (refused when they are all 0 or one is negative), and only the
  // joints that move some vertex of the primitive, renumbered in the skin's order. An
  // influence of weight 0 naming a joint the skin lacks is dropped.
  Skin BindPrimitive(const SkinJoints& joints, size_t node, const tinygltf::Primitive& primitive,
                     const std::string& pointer, size_t vertices) const;

  // What BindPrimitive accepted in a primitive that glTF forbids, said once per primitive.
  struct WeightFixes {
    // Vertices whose weights sum further than kWeightSumTolerance from 1 (closer sums are
    // rounding, normalised without a word), and the sum furthest from 1.
    size_t renormalised = 0;
    double furthestSum = 1;
    size_t furthestVertex = 0;
    // Influences of weight 0 naming a joint past the skin's, and where the first is.
    size_t ignoredJoints = 0;
    int ignoredJointsAccessor = -1;
    size_t firstIgnoredVertex = 0;

    void Renormalise(double sum, size_t vertex);
    void IgnoreJoint(int jointsAccessor, size_t vertex);
  };
  void WarnOfWeightFixes(const WeightFixes& fixes, int weightsAccessor, size_t node, size_t vertices) const;

  // The morph targets and skin of node i's primitive p, or none when it has neither.
  std::shared_ptr<const Deformation> PrimitiveDeformation(size_t node, const SkinJoints* skin,
                                                          const tinygltf::Primitive& primitive,
                                                          const std::string& pointer, const TriangleMesh& mesh) const;

  // ---- lights and camera ----------------------------------------------------------------

  // The file's lights, or (with none) AddDefaultLight's. After AddCamera: the default light
  // is placed by the camera.
  void AddLights(Scene& scene) const;
  void AddDefaultLight(Scene& scene) const;

  void AddCamera(Scene& scene);

  // No camera in the file: one framing the union of the shapes' bounds over the animation's
  // frames, as for OBJ (import::FramingPose).
  void FrameBounds(Scene& scene) const;
  import::BoundingBox AnimationBounds(const Scene& scene) const;

  const ImportInput& input_;
  const ImportOptions& options_;
  tinygltf::Model model_;
  gltf::EmbeddedData embedded_;  // while loading: the data URIs, decoded
  mutable uint64_t valueBytesRead_ = 0;  // by ReadAccessor, against kValueBytesPerBufferByte
  size_t fileBufferBytes_ = 0;           // the file's own buffers, before anything is decoded
  std::set<size_t> fallbackBuffers_;     // EXT_meshopt_compression's buffers without data
  std::set<int> dracoAccessors_;         // accessors that already read a decoded Draco mesh
  mutable std::vector<ImportWarning> warnings_;  // as Warn gave them
  // Per glTF image that a material uses: its bytes and their hash (Texture::asset).
  mutable std::map<int, std::pair<std::shared_ptr<const std::string>, std::string>> imageBytes_;
  std::vector<int> materialIndex_;  // per glTF material, its index in the scene
  struct SharedPrimitive {
    std::string name;  // in Scene::meshes; empty for a primitive without area
    std::shared_ptr<const TriangleMesh> mesh;
  };
  std::map<std::pair<size_t, size_t>, SharedPrimitive> sharedPrimitives_;  // by (mesh, primitive)
  std::vector<int> parent_;         // per node, its parent or -1
  std::vector<bool> inScene_;
  std::vector<int> order_;  // the chosen scene's nodes, parents before children
  int animation_ = -1;
  bool cameraFromFile_ = false;  // AddCamera found the file's camera
  int frameCount_ = 1;
  std::vector<std::shared_ptr<const Motion>> motions_;  // per node, its world motion
  std::vector<std::map<std::string, Channel>> channels_;  // per node, its channels by path
  std::map<size_t, SkinJoints> skins_;                    // by skin, once a node binds it
};

}  // namespace tcfarm::gltf
