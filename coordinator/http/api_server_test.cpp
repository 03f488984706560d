// The HTTP API through a real server on a free port, a real JobStore in a temporary SQLite
// file and a fake farm; the client is httplib's, so requests cross a real socket.
#include "coordinator/http/api_server.h"

#include <gtest/gtest.h>
#include <httplib.h>
#include <prometheus/counter.h>
#include <prometheus/registry.h>
#include <prometheus/text_serializer.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <regex>
#include <sstream>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include "proto/frame/frame_io.h"
#include "proto/scene/scene.h"
#include "proto/wire/content_hash.h"
#include "coordinator/store/frame_finisher.h"
#include "tests/support/cpp/required_tool.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int64_t kNowMs = 1714566896789;  // 2024-05-01T12:34:56.789Z
constexpr size_t kMaxBodyBytes = 64u << 10;
// Above the JSON routes' limit, so the test shows each route keeps to its own.
constexpr uint64_t kAssetMaxFileBytes = uint64_t{1} << 20;
constexpr uint64_t kAssetMaxJobBytes = uint64_t{2} << 20;

class FakeFarm : public FarmControl {
 public:
  void RequestCancel(uint64_t jobId) override {
    std::lock_guard<std::mutex> lock(mutex_);
    canceled_.push_back(jobId);
  }
  void RequestPriority(uint64_t jobId, int priority) override {
    std::lock_guard<std::mutex> lock(mutex_);
    priorities_.emplace_back(jobId, priority);
  }
  bool ReleaseJob(uint64_t jobId) override {
    std::lock_guard<std::mutex> lock(mutex_);
    released_.push_back(jobId);
    return !stopped_;
  }
  FarmSnapshot Snapshot() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return snapshot_;
  }
  std::vector<WorkerBan> Bans() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return bans_;
  }
  bool LiftBan(const std::string& principal) override {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto banned = std::find_if(bans_.begin(), bans_.end(), [&](const WorkerBan& b) { return b.principal == principal; });
    if (banned == bans_.end()) return false;
    bans_.erase(banned);
    return true;
  }
  void Ban(WorkerBan ban) {
    std::lock_guard<std::mutex> lock(mutex_);
    bans_.push_back(std::move(ban));
  }
  std::vector<uint64_t> Canceled() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return canceled_;
  }
  std::vector<std::pair<uint64_t, int>> Priorities() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return priorities_;
  }
  std::vector<uint64_t> Released() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return released_;
  }
  void Stop() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
  }
  void Resume() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = false;
    released_.clear();
  }
  void SetSnapshot(FarmSnapshot snapshot) {
    std::lock_guard<std::mutex> lock(mutex_);
    snapshot_ = std::move(snapshot);
  }

 private:
  mutable std::mutex mutex_;
  std::vector<uint64_t> canceled_;
  std::vector<WorkerBan> bans_;
  std::vector<std::pair<uint64_t, int>> priorities_;
  std::vector<uint64_t> released_;
  bool stopped_ = false;
  FarmSnapshot snapshot_;
};

// 8x6 pixels, frames 0..9, one sphere.
json SmallScene() {
  return json{{"camera", {{"position", {0, 0, 5}}, {"look_at", {0, 0, 0}}}},
              {"shapes", json::array({{{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 1}}})},
              {"render", {{"width", 8}, {"height", 6}, {"frames", {{"start", 0}, {"count", 10}}}}}};
}

json Submission(json scene = SmallScene()) { return json{{"scene", std::move(scene)}}; }

std::string RunCommand(const std::string& command, int* exitStatus) {
  std::string output;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) {
    *exitStatus = -1;
    return output;
  }
  char buffer[4096];
  size_t got = 0;
  while ((got = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) output.append(buffer, got);
  const int status = pclose(pipe);
  *exitStatus = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return output;
}

// Sends raw bytes and returns what the server answers until it closes or stays silent for
// 3 s: for requests httplib::Client never writes.
std::string RawExchange(int port, const std::string& request) {
  const int socketFd = socket(AF_INET, SOCK_STREAM, 0);
  if (socketFd < 0) return "";
  timeval timeout{3, 0};
  setsockopt(socketFd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  inet_pton(AF_INET, "127.0.0.1", &address.sin_addr);
  std::string answer;
  if (connect(socketFd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
      send(socketFd, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size())) {
    char buffer[4096];
    ssize_t got = 0;
    while ((got = recv(socketFd, buffer, sizeof buffer, 0)) > 0) {
      answer.append(buffer, static_cast<size_t>(got));
    }
  }
  close(socketFd);
  return answer;
}

// The project's virtual environment first, then the system's python3; "" when neither
// can import the modules (the spec checks are then skipped, not failed).
std::string PythonWith(const std::string& modules) {
  const std::string venvPython = (fs::path(TCFARM_SOURCE_DIR) / ".venv" / "bin" / "python").string();
  for (const std::string& python : {venvPython, std::string("python3")}) {
    int status = 0;
    RunCommand("'" + python + "' -c 'import " + modules + "' 2>/dev/null", &status);
    if (status == 0) return python;
  }
  return "";
}

const fs::path kOpenApiSpec = fs::path(TCFARM_SOURCE_DIR) / "proto" / "openapi.yaml";

class ApiServerTest : public ::testing::Test {
 protected:
  static constexpr uint64_t kFarmMemoryBytes = uint64_t{64} << 20;

  void SetUp() override {
    std::random_device random;
    folder_ = fs::temp_directory_path() /
              ("tcfarm_api_" + std::to_string(random()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(folder_ / "store");
    store_ = std::make_unique<JobStore>(folder_ / "jobs.sqlite", [this] { return nowMs_.load(); });
    registry_ = std::make_shared<prometheus::Registry>();
    auto& requests = prometheus::BuildCounter()
                         .Name("tcfarm_test_renders_total")
                         .Help("Renders the test pretends to have done.")
                         .Register(*registry_);
    requests.Add({{"strategy", "search"}}).Increment(3);

    ApiOptions options;
    options.host = "127.0.0.1";
    options.port = 0;
    options.maxBodyBytes = kMaxBodyBytes;
    options.storeRoot = folder_ / "store";
    options.farmMemoryBytes = kFarmMemoryBytes;
    options.assetMaxFileBytes = kAssetMaxFileBytes;
    options.assetMaxJobBytes = kAssetMaxJobBytes;
    server_ = std::make_unique<ApiServer>(*store_, farm_, registry_, options);
    port_ = server_->Start();
    client_ = std::make_unique<httplib::Client>("127.0.0.1", port_);
  }

  void TearDown() override {
    client_.reset();
    server_.reset();
    store_.reset();
    fs::remove_all(folder_);
  }

  httplib::Result Post(const std::string& path, const json& body) {
    return client_->Post(path.c_str(), body.dump(), "application/json");
  }
  httplib::Result PostText(const std::string& path, const std::string& body) {
    return client_->Post(path.c_str(), body, "application/json");
  }
  httplib::Result Get(const std::string& path) { return client_->Get(path.c_str()); }

  // Submits and returns the new job's id.
  uint64_t SubmitOk(json body = Submission()) {
    httplib::Result result = Post("/api/v1/jobs", body);
    EXPECT_TRUE(result);
    if (!result) return 0;
    EXPECT_EQ(result->status, 201) << result->body;
    return json::parse(result->body).at("id").get<uint64_t>();
  }

  // Uploads bytes as an asset and returns its hash.
  std::string PutAssetOk(const std::string& bytes) {
    const std::string hash = wire::Sha256Hex(bytes);
    httplib::Result result = client_->Put(("/api/v1/assets/" + hash).c_str(), bytes, "application/octet-stream");
    EXPECT_TRUE(result);
    if (result) {
      EXPECT_TRUE(result->status == 201 || result->status == 200) << result->body;
    }
    return hash;
  }

  // For a second server on the same store and farm.
  ApiOptions SecondServerOptions() const {
    ApiOptions options;
    options.host = "127.0.0.1";
    options.port = 0;
    options.storeRoot = folder_ / "store";
    return options;
  }

  fs::path FramePath(uint64_t id, int frame, const std::string& extension) const {
    return folder_ / "store" / std::to_string(id) / (FrameFileStem(frame) + "." + extension);
  }

  fs::path folder_;
  std::atomic<int64_t> nowMs_{kNowMs};
  std::unique_ptr<JobStore> store_;
  FakeFarm farm_;
  std::shared_ptr<prometheus::Registry> registry_;
  std::unique_ptr<ApiServer> server_;
  int port_ = 0;
  std::unique_ptr<httplib::Client> client_;
};

// Checks the one error shape and returns its "error" member.
json ExpectError(const httplib::Result& result, int status, const std::string& code) {
  EXPECT_TRUE(result);
  if (!result) return json::object();
  EXPECT_EQ(result->status, status) << result->body;
  EXPECT_EQ(result->get_header_value("Content-Type"), "application/json");
  json body = json::parse(result->body, nullptr, false);
  EXPECT_TRUE(body.is_object() && body.size() == 1 && body.contains("error")) << result->body;
  if (!body.is_object() || !body.contains("error")) return json::object();
  const json& error = body["error"];
  EXPECT_EQ(error.value("status", 0), status);
  EXPECT_EQ(error.value("code", ""), code) << result->body;
  EXPECT_TRUE(error.contains("message") && error["message"].is_string() &&
              !error["message"].get<std::string>().empty());
  return error;
}

void ExpectBadField(const httplib::Result& result, const std::string& code, const std::string& pointer,
                    const std::string& messagePart = "") {
  const json error = ExpectError(result, 400, code);
  EXPECT_EQ(error.value("pointer", "<none>"), pointer) << error.dump();
  EXPECT_NE(error.value("message", "").find(messagePart), std::string::npos) << error.dump();
}

// --- submit ------------------------------------------------------------------------------

TEST_F(ApiServerTest, SubmitStoresTheCanonicalSceneAndAnswersCreated) {
  json body = Submission();
  body["name"] = "ball";
  httplib::Result result = Post("/api/v1/jobs", body);
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 201) << result->body;
  const json job = json::parse(result->body);
  const uint64_t id = job.at("id").get<uint64_t>();
  EXPECT_EQ(result->get_header_value("Location"), "/api/v1/jobs/" + std::to_string(id));
  EXPECT_EQ(result->get_header_value("Content-Type"), "application/json");

  const std::optional<JobRecord> record = store_->Get(id);
  ASSERT_TRUE(record);
  const std::string canonical = SerializeScene(ParseScene(SmallScene().dump()));
  EXPECT_EQ(record->spec.sceneJson, canonical);
  EXPECT_EQ(record->spec.sceneHash, wire::Sha256Hex(canonical));
  EXPECT_EQ(record->spec.name, "ball");

  EXPECT_EQ(job["name"], "ball");
  EXPECT_EQ(job["state"], "queued");
  EXPECT_EQ(job["strategy"], "search");
  EXPECT_EQ(job["bin_width"], 10);
  EXPECT_EQ(job["tolerance"], 0.0);
  EXPECT_EQ(job["priority"], 0);
  EXPECT_EQ(job["width"], 8);
  EXPECT_EQ(job["height"], 6);
  EXPECT_EQ(job["frames"], (json{{"start", 0}, {"end", 9}, {"count", 10}, {"done", 0}}));
  EXPECT_EQ(job["progress"], 0.0);
  EXPECT_EQ(job["submitted_at"], "2024-05-01T12:34:56.789Z");
  EXPECT_TRUE(job["started_at"].is_null());
  EXPECT_TRUE(job["finished_at"].is_null());
  EXPECT_FALSE(job.contains("error"));
  EXPECT_EQ(job["traced_per_frame"], json(std::vector<int>(10, -1)));
  EXPECT_EQ(job["links"]["self"], "/api/v1/jobs/" + std::to_string(id));
  EXPECT_EQ(job["links"]["frames"], "/api/v1/jobs/" + std::to_string(id) + "/frames/{frame}.png");
}

TEST_F(ApiServerTest, EqualScenesWrittenDifferentlyGetTheSameHash) {
  const uint64_t first = SubmitOk();
  const std::string reordered =
      R"({"scene": {"render": {"height": 6, "frames": {"count": 10, "start": 0}, "width": 8},
                    "shapes": [{"radius": 1.0, "center": [0, 0, 0], "type": "sphere"}],
                    "camera": {"look_at": [0, 0, 0], "position": [0, 0, 5.0]}}})";
  httplib::Result result = PostText("/api/v1/jobs", reordered);
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 201) << result->body;
  const uint64_t second = json::parse(result->body).at("id").get<uint64_t>();
  EXPECT_EQ(store_->Get(first)->spec.sceneHash, store_->Get(second)->spec.sceneHash);
}

TEST_F(ApiServerTest, SubmitTakesEveryOptionalField) {
  json body = Submission();
  body["frames"] = {{"start", 2}, {"end", 7}};
  body["strategy"] = "brute";
  body["bin_width"] = 5;
  body["tolerance"] = 0.25;
  body["priority"] = -100;
  const uint64_t id = SubmitOk(body);
  const JobSpec spec = store_->Get(id)->spec;
  EXPECT_EQ(spec.firstFrame, 2);
  EXPECT_EQ(spec.lastFrame, 7);
  EXPECT_EQ(spec.strategy, Strategy::kBrute);
  EXPECT_EQ(spec.binWidth, 5);
  EXPECT_EQ(spec.tolerance, 0.25);
  EXPECT_EQ(spec.priority, -100);
  // Read from the scene parsed at submit, so that the farm need not parse it again.
  EXPECT_EQ(spec.frameSize.width, 8);
  EXPECT_EQ(spec.frameSize.height, 6);
  EXPECT_EQ(spec.cameraOrLightsChange, std::optional<bool>(false));

  // One end alone keeps the scene's other end; a single frame is a range too.
  body = Submission();
  body["frames"] = {{"start", 9}};
  const JobSpec last = store_->Get(SubmitOk(body))->spec;
  EXPECT_EQ(last.firstFrame, 9);
  EXPECT_EQ(last.lastFrame, 9);
}

TEST_F(ApiServerTest, BodyThatIsNotJsonIsInvalidJson) {
  const json error = ExpectError(PostText("/api/v1/jobs", "{\"scene\": "), 400, "invalid_json");
  EXPECT_NE(error["message"].get<std::string>().find("not valid JSON"), std::string::npos);
  EXPECT_FALSE(error.contains("pointer"));
  ExpectError(PostText("/api/v1/jobs", ""), 400, "invalid_json");
  ExpectError(PostText("/api/v1/jobs", "{\"tolerance\": 1e999}"), 400, "invalid_json");
}

// A body nested 100000 deep (and more than some 50000) once crashed the coordinator: writing it back out for a
// message recursed once per level.
TEST_F(ApiServerTest, DeeplyNestedBodiesAreRefusedNotFollowed) {
  for (const std::string& open : {std::string("["), std::string("{\"a\":")}) {
    std::string deep;
    for (int i = 0; i < 10000; ++i) deep += open;
    const json error = ExpectError(PostText("/api/v1/jobs", "{\"scene\": " + deep), 400, "invalid_json");
    EXPECT_NE(error["message"].get<std::string>().find("nested deeper than 128 levels"), std::string::npos)
        << error;
  }
  const json error = ExpectError(PostText("/api/v1/jobs", "{\"name\": " + std::string(200, '[') +
                                                              std::string(200, ']') + "}"),
                                 400, "invalid_json");
  EXPECT_EQ(error["pointer"], "/name" + [] {
    std::string pointer;
    for (int i = 0; i < 127; ++i) pointer += "/0";
    return pointer;
  }());
  // A scene at ordinary depth still goes through.
  SubmitOk(Submission());
}

// The coordinator holds a job's frames in memory: a job whose frames would not fit in the
// farm's memory even alone and one bin at a time is refused at submit, saying what it
// needs and what the farm has, instead of waiting forever or exhausting the machine.
TEST_F(ApiServerTest, JobsWhoseFramesExceedTheFarmsMemoryAreRefused) {
  json scene = SmallScene();
  scene["render"]["width"] = 1024;
  scene["render"]["height"] = 1024;  // 12 MiB a frame; a 10-frame search holds 14 of them
  const json error = ExpectError(Post("/api/v1/jobs", Submission(scene)), 413, "job_too_large");
  EXPECT_EQ(error["pointer"], "/scene/render");
  EXPECT_EQ(error["message"],
            "a 1024x1024 frame takes 12.0 MiB as float RGB, and this job of 10 frames holds up to 14 of "
            "them at once even one bin at a time: it needs 168.0 MiB with its other state; the farm has "
            "64.0 MiB for all its running jobs (--farm-memory); expected fewer pixels a frame, a narrower bin_width or a coordinator with more memory");
  // At 3 MiB a frame over 60 frames, it depends on what the planner holds: a bin of 20
  // frames is too much, a bin of 5 fits, and so does exact's one working frame.
  scene["render"]["width"] = 512;
  scene["render"]["height"] = 512;
  scene["render"]["frames"]["count"] = 60;
  json body = Submission(scene);
  body["bin_width"] = 20;
  ExpectError(Post("/api/v1/jobs", body), 413, "job_too_large");
  body["bin_width"] = 5;
  SubmitOk(body);
  body["strategy"] = "exact";
  body["bin_width"] = 60;
  SubmitOk(body);
  // auto is checked as the farm will run it: exact for this still camera, guarded with
  // bins of up to 16 frames once the camera moves.
  body["strategy"] = "auto";
  SubmitOk(body);
  body["scene"]["camera"]["position"] = {{"polynomial", {{0, 0.1}, {0, 0}, {5, 0}}}};
  ExpectError(Post("/api/v1/jobs", body), 413, "job_too_large");
}

TEST_F(ApiServerTest, DuplicateKeysAreRefusedWithTheirPointer) {
  const std::string body =
      R"({"scene": {"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
                    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "radius": 2}],
                    "render": {"width": 8, "height": 6}}})";
  ExpectBadField(PostText("/api/v1/jobs", body), "invalid_json", "/scene/shapes/0/radius", "duplicate");
  ExpectBadField(PostText("/api/v1/jobs", R"({"priority": 1, "priority": 2})"), "invalid_json",
                 "/priority");
}

TEST_F(ApiServerTest, BodyMustBeAnObjectWithAScene) {
  ExpectBadField(PostText("/api/v1/jobs", "[1, 2]"), "invalid_field", "");
  ExpectBadField(Post("/api/v1/jobs", json{{"name", "no scene"}}), "missing_field", "/scene");
}

TEST_F(ApiServerTest, UnknownFieldsAreNamed) {
  json body = Submission();
  body["colour/space"] = "srgb";
  ExpectBadField(Post("/api/v1/jobs", body), "unknown_field", "/colour~1space", "bin_width");
  body = Submission();
  body["frames"] = {{"start", 0}, {"stop", 3}};
  ExpectBadField(Post("/api/v1/jobs", body), "unknown_field", "/frames/stop");
}

TEST_F(ApiServerTest, BadSceneNamesItsPointerInsideTheBody) {
  json scene = SmallScene();
  scene["shapes"].push_back({{"type", "sphere"}, {"center", {1, 0, 0}}, {"radius", -1}});
  const json error = ExpectError(Post("/api/v1/jobs", Submission(scene)), 400, "invalid_scene");
  EXPECT_EQ(error.value("pointer", ""), "/scene/shapes/1/radius");
  EXPECT_EQ(error["message"].get<std::string>().rfind("scene/shapes/1/radius: -1", 0), 0u) << error;

  ExpectBadField(Post("/api/v1/jobs", json{{"scene", "not a scene"}}), "invalid_scene", "/scene");
}

TEST_F(ApiServerTest, MeshFileReferencesAreRefused) {
  json scene = SmallScene();
  scene["shapes"].push_back({{"type", "mesh"}, {"file", "/etc/passwd"}});
  ExpectBadField(Post("/api/v1/jobs", Submission(scene)), "invalid_scene", "/scene/shapes/1/file");
}

TEST_F(ApiServerTest, FramesMustLieInsideTheScenesRange) {
  json body = Submission();
  body["frames"] = {{"start", 2}, {"end", 10}};
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/frames/end", "[0, 9]");
  body["frames"] = {{"start", -1}, {"end", 3}};
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/frames/start");
  body["frames"] = {{"start", 5}, {"end", 3}};
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/frames/end", "before");
  body["frames"] = {{"start", 1.5}};
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/frames/start", "integer");
  body["frames"] = json::array({0, 3});
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/frames");
}

// The import options are read by the scene's own reader (import_options.h): its bounds and
// words, at the submission's pointers.
TEST_F(ApiServerTest, ImportOptionsAreCheckedAsAScenesAre) {
  const json file{{"scene_file", "shot.glb"}};
  auto refused = [&](const json& import) {
    json body = file;
    body["import"] = import;
    return Post("/api/v1/jobs", body);
  };
  ExpectBadField(refused({{"spp", 0}}), "invalid_field", "/import/spp",
                 "import/spp: 0 is out of range; expected samples per pixel, an integer in [1, 1024]");
  ExpectBadField(refused({{"size", {64, 16385}}}), "invalid_field", "/import/size/1",
                 "import/size/1: 16385 is out of range; expected a width or height in pixels");
  ExpectBadField(refused({{"size", 64}}), "invalid_field", "/import/size", "expected [width, height]");
  ExpectBadField(refused({{"fps", -1}}), "invalid_field", "/import/fps", "frames per second in [0.001, 100000]");
  ExpectBadField(refused({{"camera", 1.5}}), "invalid_field", "/import/camera", "a name or an index");
  ExpectBadField(refused({{"speed", 2}}), "unknown_field", "/import/speed", "only the fields");
}

TEST_F(ApiServerTest, StrategyMustBeOneThatRunsToday) {
  json body = Submission();
  for (const StrategyNameEntry& entry : kStrategyNames) {
    body["strategy"] = entry.name;
    auto result = Post("/api/v1/jobs", body);
    ASSERT_TRUE(result);
    EXPECT_EQ(result->status, 201) << entry.name << ": " << result->body;
  }
  body["strategy"] = "magic";
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/strategy",
                 R"(one of "search", "brute", "guarded", "exact", "auto")");
  body["strategy"] = 3;
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/strategy");
}

TEST_F(ApiServerTest, VerificationRequestsAreStoredWithTheJob) {
  json body = Submission();
  body["verify"] = {{"sample", 3}};
  body["spot_check_share"] = 0.015;
  auto result = Post("/api/v1/jobs", body);
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 201) << result->body;
  uint64_t id = json::parse(result->body)["id"].get<uint64_t>();
  auto stored = store_->Get(id);
  ASSERT_TRUE(stored);
  EXPECT_EQ(stored->spec.options["verify"], json({{"sample", 3}}));
  EXPECT_DOUBLE_EQ(stored->spec.options["spot_check_share"].get<double>(), 0.015);
}

TEST_F(ApiServerTest, ThePreviewsViewIsStoredAndShownWithTheJob) {
  json body = Submission();
  const json standard = json::parse(Post("/api/v1/jobs", body)->body);
  EXPECT_EQ(standard["view"], "standard");
  EXPECT_EQ(standard["exposure"], 0);
  body["view"] = "khr-pbr-neutral";
  body["exposure"] = -1.5;
  const json neutral = json::parse(Post("/api/v1/jobs", body)->body);
  EXPECT_EQ(JobPreviewView(store_->Get(neutral["id"].get<uint64_t>())->spec),
            (ViewTransform{View::kKhrPbrNeutral, -1.5}));
  const json shown = json::parse(Get("/api/v1/jobs/" + neutral["id"].dump())->body);
  EXPECT_EQ(shown["view"], "khr-pbr-neutral");
  EXPECT_EQ(shown["exposure"], -1.5);
}

TEST_F(ApiServerTest, NumbersOutOfRangeAreRefused) {
  const std::vector<std::pair<std::string, json>> bad{
      {"bin_width", 1},     {"bin_width", 1001}, {"bin_width", 2.5}, {"bin_width", "10"},
      {"tolerance", -0.1},  {"tolerance", "0"},  {"tolerance", 3.5e38}, {"tolerance", 1e308},
      {"priority", 101},    {"priority", -101},
      {"priority", 1e300},  {"name", 7},         {"name", std::string(300, 'x')},
      {"spot_check_share", 0.03}, {"spot_check_share", "0"},
      {"view", "filmic"},   {"view", 1},         {"exposure", 33},  {"exposure", "1"},
  };
  for (const auto& [field, value] : bad) {
    json body = Submission();
    body[field] = value;
    SCOPED_TRACE(field + " = " + value.dump());
    ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/" + field);
  }
  json text = Submission();
  text["spot_check_share"] = "0";
  const json error = ExpectError(Post("/api/v1/jobs", text), 400, "invalid_field");
  EXPECT_NE(error["message"].get<std::string>().find("is not a number"), std::string::npos) << error;
  // The limits themselves are fine, and an integral float is an integer.
  json body = Submission();
  body["bin_width"] = 2.0;
  body["priority"] = 100;
  body["tolerance"] = 0;
  SubmitOk(body);
  body["tolerance"] = std::numeric_limits<float>::max();
  SubmitOk(body);
}

TEST_F(ApiServerTest, BodyOverTheLimitIs413InTheErrorShape) {
  json body = Submission();
  body["name"] = std::string(kMaxBodyBytes, 'x');
  const json error = ExpectError(Post("/api/v1/jobs", body), 413, "payload_too_large");
  EXPECT_NE(error["message"].get<std::string>().find(std::to_string(kMaxBodyBytes)), std::string::npos);
  // The connection is still good for the next request.
  SubmitOk();
}

TEST_F(ApiServerTest, ChunkedBodyOverTheLimitIsRefusedToo) {
  const std::string big(2 * kMaxBodyBytes, ' ');
  httplib::Result result = client_->Post(
      "/api/v1/jobs",
      [&big](size_t offset, httplib::DataSink& sink) {
        constexpr size_t kChunk = 8192;
        if (offset >= big.size()) {
          sink.done();
        } else {
          sink.write(big.data() + offset, std::min(kChunk, big.size() - offset));
        }
        return true;
      },
      "application/json");
  ExpectError(result, 413, "payload_too_large");
}

// --- assets ------------------------------------------------------------------------------

const std::string kTriangleObj = "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n";

// SmallScene with a mesh read from an OBJ file of the submission's assets.
json SceneWithMeshFile(const std::string& file) {
  json scene = SmallScene();
  scene["shapes"].push_back({{"type", "mesh"}, {"file", file}});
  return scene;
}

size_t FilesUnder(const fs::path& folder) {
  std::error_code error;
  if (!fs::exists(folder, error)) return 0;
  size_t count = 0;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) count += entry.is_regular_file() ? 1 : 0;
  return count;
}

TEST_F(ApiServerTest, AssetUploadIsStoredUnderItsHashOnce) {
  const std::string hash = wire::Sha256Hex(kTriangleObj);
  const std::string path = "/api/v1/assets/" + hash;
  httplib::Result result = client_->Put(path.c_str(), kTriangleObj, "application/octet-stream");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 201) << result->body;
  EXPECT_EQ(json::parse(result->body), (json{{"sha256", hash}, {"size", kTriangleObj.size()}}));
  std::ifstream stored(folder_ / "store" / "assets" / hash, std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(stored), {}), kTriangleObj);
  // Again: nothing new, 200.
  result = client_->Put(path.c_str(), kTriangleObj, "application/octet-stream");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(FilesUnder(folder_ / "store" / "assets"), 1u);
  const std::string metrics = Get("/metrics")->body;
  EXPECT_NE(metrics.find("tcfarm_asset_uploads_total 2"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("tcfarm_asset_upload_bytes_total " + std::to_string(2 * kTriangleObj.size())),
            std::string::npos);
  // An empty file is an asset too.
  result = client_->Put(("/api/v1/assets/" + wire::Sha256Hex("")).c_str(), "", "application/octet-stream");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 201) << result->body;
}

TEST_F(ApiServerTest, AssetWhoseBytesDoNotMatchItsHashIsRefused) {
  const std::string hash = wire::Sha256Hex(kTriangleObj);
  const json error = ExpectError(client_->Put(("/api/v1/assets/" + hash).c_str(), kTriangleObj + "\n",
                                              "application/octet-stream"),
                                 400, "asset_hash_mismatch");
  EXPECT_NE(error["message"].get<std::string>().find(wire::Sha256Hex(kTriangleObj + "\n")), std::string::npos);
  EXPECT_EQ(FilesUnder(folder_ / "store" / "assets"), 0u);
  for (const std::string& bad : {std::string(63, 'a'), std::string(64, 'A'), std::string("missing")}) {
    ExpectError(client_->Put(("/api/v1/assets/" + bad).c_str(), kTriangleObj, "application/octet-stream"), 400,
                "invalid_parameter");
  }
  // The connection is still good for the next request.
  PutAssetOk(kTriangleObj);
}

TEST_F(ApiServerTest, AssetOverItsLimitIs413NamingTheLimit) {
  const std::string big(kAssetMaxFileBytes + 1, 'x');
  const json error = ExpectError(client_->Put(("/api/v1/assets/" + wire::Sha256Hex(big)).c_str(), big,
                                              "application/octet-stream"),
                                 413, "payload_too_large");
  EXPECT_NE(error["message"].get<std::string>().find(std::to_string(kAssetMaxFileBytes) + " bytes"), std::string::npos);
  EXPECT_NE(error["message"].get<std::string>().find("--asset-max-file-mib"), std::string::npos);
  // Chunked, so no Content-Length tells the size before the bytes come.
  httplib::Result chunked = client_->Put(
      ("/api/v1/assets/" + wire::Sha256Hex(big)).c_str(),
      [&big](size_t offset, httplib::DataSink& sink) {
        constexpr size_t kChunk = 65536;
        if (offset >= big.size()) {
          sink.done();
        } else {
          sink.write(big.data() + offset, std::min(kChunk, big.size() - offset));
        }
        return true;
      },
      "application/octet-stream");
  ExpectError(chunked, 413, "payload_too_large");
  EXPECT_EQ(FilesUnder(folder_ / "store" / "assets"), 0u);
  // At the limit, larger than the JSON routes' limit, is fine.
  PutAssetOk(std::string(kAssetMaxFileBytes, 'y'));
}

TEST_F(ApiServerTest, MissingAssetsAreTheHashesTheStoreLacks) {
  const std::string have = PutAssetOk(kTriangleObj);
  const std::string lack = wire::Sha256Hex("not uploaded");
  httplib::Result result = Post("/api/v1/assets/missing", json{{"hashes", {have, lack, lack}}});
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(json::parse(result->body), (json{{"missing", {lack}}}));
  result = Post("/api/v1/assets/missing", json{{"hashes", json::array()}});
  ASSERT_TRUE(result);
  EXPECT_EQ(json::parse(result->body), (json{{"missing", json::array()}}));

  ExpectBadField(Post("/api/v1/assets/missing", json{{"hashes", {have, "../../jobs.sqlite"}}}), "invalid_field",
                 "/hashes/1", "not a SHA-256");
  ExpectBadField(Post("/api/v1/assets/missing", json{{"hashes", have}}), "invalid_field", "/hashes");
  ExpectBadField(Post("/api/v1/assets/missing", json::object()), "missing_field", "/hashes");
  ExpectBadField(Post("/api/v1/assets/missing", json{{"hashes", json::array()}, {"more", 1}}), "unknown_field",
                 "/more");
  ExpectError(PostText("/api/v1/assets/missing", "{"), 400, "invalid_json");
  httplib::Result wrong = Get("/api/v1/assets/" + have);
  ExpectError(wrong, 405, "method_not_allowed");
  EXPECT_EQ(wrong->get_header_value("Allow"), "PUT");
}

TEST_F(ApiServerTest, MeshFilesComeFromTheSubmissionsAssets) {
  const std::string hash = PutAssetOk(kTriangleObj);
  json body = Submission(SceneWithMeshFile("meshes/tri.obj"));
  body["assets"] = {{"meshes/tri.obj", hash}};
  const JobSpec spec = store_->Get(SubmitOk(body))->spec;
  // The stored scene is self-contained: the mesh is inline, the workers need no file.
  const json stored = json::parse(spec.sceneJson);
  EXPECT_FALSE(stored["shapes"][1].contains("file")) << stored["shapes"][1];
  EXPECT_EQ(stored["shapes"][1]["triangles"], json::array({json::array({0, 1, 2})}));
  EXPECT_EQ(spec.sceneHash, wire::Sha256Hex(spec.sceneJson));
  // The folder the scene was parsed in is gone; the asset stays.
  EXPECT_TRUE(fs::is_empty(folder_ / "store" / "assets" / ".submissions"));
  EXPECT_EQ(FilesUnder(folder_ / "store" / "assets"), 1u);
}

TEST_F(ApiServerTest, AnUploadedSceneFileIsImportedByItsType) {
  const std::string obj = "mtllib red.mtl\nusemtl red\n" + kTriangleObj;
  const json base{{"scene_file", "shot.obj"},
               {"assets", {{"shot.obj", PutAssetOk(obj)}, {"red.mtl", PutAssetOk("newmtl red\nKd 1 0 0\n")}}},
               {"name", "obj"}};
  const JobSpec spec = store_->Get(SubmitOk(base))->spec;
  const json stored = json::parse(spec.sceneJson);
  ASSERT_EQ(stored["shapes"].size(), 1u);
  EXPECT_EQ(spec.name, "obj");
  EXPECT_GT(spec.frameSize.width, 0);

  // Without its library the OBJ says which line asked for it.
  json body = base;
  body["assets"].erase("red.mtl");
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_scene", "/scene_file", "red.mtl");
  body = base;
  body["scene_file"] = "other.obj";
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/scene_file", "not among the assets");
  body = base;
  body["scene"] = SmallScene();
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/scene_file", "not both");
  body = base;
  body["scene_file"] = 3;
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/scene_file");

  // A JSON scene file in a folder of the assets: its mesh files resolve beside it.
  body = json{{"scene_file", "shots/one.json"},
              {"assets", {{"shots/one.json", PutAssetOk(SceneWithMeshFile("tri.obj").dump())},
                          {"shots/tri.obj", PutAssetOk(kTriangleObj)}}}};
  EXPECT_EQ(json::parse(store_->Get(SubmitOk(body))->spec.sceneJson)["shapes"].size(), 2u);
  body["assets"].erase("shots/tri.obj");
  body["assets"]["tri.obj"] = wire::Sha256Hex(kTriangleObj);
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_scene", "/scene_file", "tri.obj");
}

TEST_F(ApiServerTest, AssetPathsThatCouldEscapeTheFolderAreRefusedWithTheirPointer) {
  const std::string hash = PutAssetOk(kTriangleObj);
  const std::vector<std::pair<std::string, std::string>> bad{
      {"../tri.obj", "/assets/..~1tri.obj"},
      {"meshes/../../tri.obj", "/assets/meshes~1..~1..~1tri.obj"},
      {"/etc/passwd", "/assets/~1etc~1passwd"},
      {"./tri.obj", "/assets/.~1tri.obj"},
      {std::string("tri\0.obj", 8), std::string("/assets/tri\0.obj", 16)},
      {std::string(2000, 'a'), "/assets/" + std::string(2000, 'a')},
  };
  for (const auto& [path, pointer] : bad) {
    json body = Submission(SceneWithMeshFile("tri.obj"));
    body["assets"] = {{path, hash}};
    SCOPED_TRACE(pointer.substr(0, 40));
    ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", pointer, "refused");
  }
  json body = Submission(SceneWithMeshFile("tri.obj"));
  body["assets"] = {{"tri.obj", "TRI"}};
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/assets/tri.obj", "not a SHA-256");
  body["assets"] = {{"tri.obj", hash}, {"tri.obj/inner.obj", hash}};
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/assets", "both a file and a folder");
  body["assets"] = json::array({hash});
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_field", "/assets");
  // The scene may only reach its own assets, whatever it writes.
  body = Submission(SceneWithMeshFile("../tri.obj"));
  body["assets"] = {{"tri.obj", hash}};
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_scene", "/scene/shapes/1/file", "outside the scene folder");
  body = Submission(SceneWithMeshFile("other.obj"));
  body["assets"] = {{"tri.obj", hash}};
  ExpectBadField(Post("/api/v1/jobs", body), "invalid_scene", "/scene/shapes/1/file", "other.obj");
  // No job was written, and no folder is left.
  EXPECT_TRUE(store_->List(std::nullopt, 10).empty());
  EXPECT_TRUE(fs::is_empty(folder_ / "store" / "assets" / ".submissions"));
}

TEST_F(ApiServerTest, AnAssetTheFarmLacksIsNamed) {
  const std::string lack = wire::Sha256Hex(kTriangleObj);
  json body = Submission(SceneWithMeshFile("tri.obj"));
  body["assets"] = {{"tri.obj", lack}};
  const json error = ExpectError(Post("/api/v1/jobs", body), 400, "missing_asset");
  EXPECT_EQ(error["pointer"], "/assets/tri.obj");
  EXPECT_NE(error["message"].get<std::string>().find(lack), std::string::npos);
  EXPECT_TRUE(store_->List(std::nullopt, 10).empty());
}

TEST_F(ApiServerTest, AssetsPastTheJobLimitAre413NamingTheLimit) {
  const std::string first = PutAssetOk(std::string(kAssetMaxFileBytes, 'a'));
  const std::string second = PutAssetOk(std::string(kAssetMaxFileBytes, 'b'));
  const std::string third = PutAssetOk(kTriangleObj);
  json body = Submission(SceneWithMeshFile("tri.obj"));
  body["assets"] = {{"a.bin", first}, {"b.bin", second}, {"tri.obj", third}};
  const json error = ExpectError(Post("/api/v1/jobs", body), 413, "job_too_large");
  EXPECT_EQ(error["pointer"], "/assets");
  EXPECT_NE(error["message"].get<std::string>().find("allows 2 MiB per job (--asset-max-job-mib)"), std::string::npos)
      << error;
  body["assets"].erase("b.bin");
  SubmitOk(body);
}

// --- list and get ------------------------------------------------------------------------

TEST_F(ApiServerTest, ListIsNewestFirstAndFilters) {
  const uint64_t first = SubmitOk();
  const uint64_t second = SubmitOk();
  const uint64_t third = SubmitOk();
  ASSERT_TRUE(store_->ClaimNext());  // the oldest of equal priority: first
  ASSERT_TRUE(store_->Cancel(second));

  httplib::Result all = Get("/api/v1/jobs");
  ASSERT_TRUE(all);
  ASSERT_EQ(all->status, 200) << all->body;
  const json jobs = json::parse(all->body).at("jobs");
  ASSERT_EQ(jobs.size(), 3u);
  EXPECT_EQ(jobs[0]["id"], third);
  EXPECT_EQ(jobs[1]["id"], second);
  EXPECT_EQ(jobs[2]["id"], first);
  EXPECT_EQ(jobs[2]["width"], 8);  // geometry for list records, whose scene is not loaded
  EXPECT_FALSE(jobs[0].contains("traced_per_frame"));

  const json running = json::parse(Get("/api/v1/jobs?state=running")->body).at("jobs");
  ASSERT_EQ(running.size(), 1u);
  EXPECT_EQ(running[0]["id"], first);
  const json queued = json::parse(Get("/api/v1/jobs?state=queued")->body).at("jobs");
  ASSERT_EQ(queued.size(), 1u);
  EXPECT_EQ(queued[0]["id"], third);
  EXPECT_EQ(json::parse(Get("/api/v1/jobs?state=completed")->body).at("jobs"), json::array());

  const json limited = json::parse(Get("/api/v1/jobs?limit=2")->body).at("jobs");
  ASSERT_EQ(limited.size(), 2u);
  EXPECT_EQ(limited[0]["id"], third);
}

TEST_F(ApiServerTest, ListRefusesBadStateOrLimit) {
  ExpectError(Get("/api/v1/jobs?state=sleeping"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs?state="), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs?limit=0"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs?limit=1001"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs?limit=-5"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs?limit=ten"), 400, "invalid_parameter");
  const json twice = ExpectError(Get("/api/v1/jobs?state=completed&state=failed"), 400, "invalid_parameter");
  EXPECT_EQ(twice["message"], "state is given 2 times; expected it at most once");
  ExpectError(Get("/api/v1/jobs?limit=1&limit=2"), 400, "invalid_parameter");
}

TEST_F(ApiServerTest, GetUnknownOrMalformedId) {
  ExpectError(Get("/api/v1/jobs/42"), 404, "job_not_found");
  ExpectError(Get("/api/v1/jobs/abc"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs/-1"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs/99999999999999999999999"), 400, "invalid_parameter");
  // Ids are int64: one past the largest is malformed, not merely unknown.
  ExpectError(Get("/api/v1/jobs/9223372036854775807"), 404, "job_not_found");
  ExpectError(Get("/api/v1/jobs/9223372036854775808"), 400, "invalid_parameter");
  // A NUL in the id is shown escaped, not allowed to cut the message short.
  const json error = ExpectError(Get("/api/v1/jobs/1%00"), 400, "invalid_parameter");
  EXPECT_EQ(error["message"], "job id \"1\\u0000\" is not a job id; expected a positive integer up to 9223372036854775807");
  const json limit = ExpectError(Get("/api/v1/jobs?limit=1%00"), 400, "invalid_parameter");
  EXPECT_NE(limit["message"].get<std::string>().find("\\u0000\" is out of range; expected"), std::string::npos) << limit;
}

TEST_F(ApiServerTest, RunningJobShowsLiveProgressAndStats) {
  const uint64_t id = SubmitOk();
  nowMs_ = kNowMs + 1000;
  ASSERT_TRUE(store_->ClaimNext());
  ASSERT_TRUE(store_->RecordFrame(id, 0, 48, 0));
  ASSERT_TRUE(store_->RecordFrame(id, 1, 12, 36));
  ASSERT_TRUE(store_->SetStats(id, json{{"rays", 100}, {"phase", "stored"}}));
  FarmSnapshot snapshot;
  snapshot.runningStats[id] = json{{"phase", "live"}, {"bins_done", 1}};
  farm_.SetSnapshot(snapshot);

  const json job = json::parse(Get("/api/v1/jobs/" + std::to_string(id))->body);
  EXPECT_EQ(job["state"], "running");
  EXPECT_EQ(job["started_at"], "2024-05-01T12:34:57.789Z");
  EXPECT_EQ(job["frames"]["done"], 2);
  EXPECT_DOUBLE_EQ(job["progress"].get<double>(), 0.2);
  EXPECT_EQ(job["pixels_traced"], 60);
  EXPECT_EQ(job["pixels_copied"], 36);
  // Finished frames only: 60 traced of 2 frames * 48 pixels.
  EXPECT_DOUBLE_EQ(job["traced_pixel_ratio"].get<double>(), 60.0 / 96.0);
  EXPECT_EQ(job["stats"], (json{{"rays", 100}, {"phase", "live"}, {"bins_done", 1}}));
  json expectedPerFrame = json(std::vector<int>(10, -1));
  expectedPerFrame[0] = 48;
  expectedPerFrame[1] = 12;
  EXPECT_EQ(job["traced_per_frame"], expectedPerFrame);

  const json listed = json::parse(Get("/api/v1/jobs?state=running")->body).at("jobs").at(0);
  EXPECT_EQ(listed["stats"]["phase"], "live");
}

TEST_F(ApiServerTest, FailedJobCarriesItsError) {
  const uint64_t id = SubmitOk();
  ASSERT_TRUE(store_->Fail(id, "scene too large for any worker"));
  const json job = json::parse(Get("/api/v1/jobs/" + std::to_string(id))->body);
  EXPECT_EQ(job["state"], "failed");
  EXPECT_EQ(job["error"], "scene too large for any worker");
  EXPECT_EQ(job["finished_at"], "2024-05-01T12:34:56.789Z");
}

// --- cancel ------------------------------------------------------------------------------

TEST_F(ApiServerTest, CancelQueuedJobNotifiesTheFarmOnce) {
  const uint64_t id = SubmitOk();
  const std::string path = "/api/v1/jobs/" + std::to_string(id) + "/cancel";
  httplib::Result result = client_->Post(path.c_str());
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(json::parse(result->body)["state"], "canceled");
  EXPECT_EQ(store_->Get(id)->state, JobState::kCanceled);
  EXPECT_EQ(farm_.Canceled(), std::vector<uint64_t>{id});

  const json error = ExpectError(client_->Post(path.c_str()), 409, "job_finished");
  EXPECT_NE(error["message"].get<std::string>().find("canceled"), std::string::npos);
  EXPECT_EQ(farm_.Canceled().size(), 1u);
}

TEST_F(ApiServerTest, CancelRunningJobAndUnknownJob) {
  const uint64_t id = SubmitOk();
  ASSERT_TRUE(store_->ClaimNext());
  httplib::Result result = client_->Post(("/api/v1/jobs/" + std::to_string(id) + "/cancel").c_str());
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 200);
  EXPECT_EQ(farm_.Canceled(), std::vector<uint64_t>{id});
  ExpectError(client_->Post("/api/v1/jobs/77/cancel"), 404, "job_not_found");
  ExpectError(client_->Post("/api/v1/jobs/x/cancel"), 400, "invalid_parameter");
}

// --- lists, retry, change, delete, frames, events ---------------------------------------

std::vector<uint64_t> IdsOf(const json& list) {
  std::vector<uint64_t> ids;
  for (const json& job : list.at("jobs")) ids.push_back(job.at("id").get<uint64_t>());
  return ids;
}

TEST_F(ApiServerTest, ListFiltersByStateStrategyAndNameAndPagesWithATotal) {
  std::vector<uint64_t> ids;
  for (const auto& [name, strategy] : std::vector<std::pair<std::string, std::string>>{
           {"Orbit one", "search"}, {"teapot", "exact"}, {"orbit two", "exact"}, {"wide", "search"},
           {"ORBIT three", "brute"}, {"last", "auto"}}) {
    json body = Submission();
    body["name"] = name;
    body["strategy"] = strategy;
    ids.push_back(SubmitOk(body));
  }
  ASSERT_TRUE(store_->Fail(ids[1], "broken"));
  ASSERT_TRUE(store_->Cancel(ids[2]));
  auto list = [&](const std::string& query) {
    httplib::Result result = Get("/api/v1/jobs" + query);
    EXPECT_TRUE(result);
    EXPECT_EQ(result->status, 200) << query << ": " << result->body;
    return json::parse(result->body);
  };
  json page = list("?offset=2&limit=2");
  EXPECT_EQ(IdsOf(page), (std::vector<uint64_t>{ids[3], ids[2]}));
  EXPECT_EQ(page["total"], 6);
  EXPECT_EQ(page["offset"], 2);
  EXPECT_EQ(page["limit"], 2);
  EXPECT_EQ(IdsOf(list("?offset=6")), std::vector<uint64_t>{});
  EXPECT_EQ(list("")["limit"], 50);
  EXPECT_EQ(IdsOf(list("?state=failed,canceled")), (std::vector<uint64_t>{ids[2], ids[1]}));
  EXPECT_EQ(IdsOf(list("?strategy=exact")), (std::vector<uint64_t>{ids[2], ids[1]}));
  page = list("?name=orBit&limit=1");
  EXPECT_EQ(IdsOf(page), std::vector<uint64_t>{ids[4]});
  EXPECT_EQ(page["total"], 3);
  EXPECT_EQ(IdsOf(list("?name=orbit&strategy=search,brute&state=queued")), (std::vector<uint64_t>{ids[4], ids[0]}));
  EXPECT_EQ(IdsOf(list("?name=orbit%20two")), std::vector<uint64_t>{ids[2]});

  for (const auto& [query, named] : std::vector<std::pair<std::string, std::string>>{
           {"?state=bogus", "state \"bogus\" is not a job state"},
           {"?state=", "state \"\" is not a job state"},
           {"?state=queued,,failed", "state \"\""},
           {"?strategy=magic", "strategy \"magic\" is not a strategy; expected one of search, brute"},
           {"?limit=0", "limit \"0\" is out of range; expected an integer in [1, 1000]"},
           {"?limit=1001", "limit"},
           {"?offset=-1", "offset \"-1\" is out of range"},
           {"?offset=two", "offset"},
           {"?offset=1&offset=2", "offset is given 2 times"},
           {"?name=" + std::string(300, 'x'), "name is 300 bytes long"}}) {
    const json error = ExpectError(Get("/api/v1/jobs" + query), 400, "invalid_parameter");
    EXPECT_NE(error.value("message", "").find(named), std::string::npos) << query << ": " << error;
  }
}

TEST_F(ApiServerTest, RetryQueuesAFailedOrCanceledJobUnderItsId) {
  const uint64_t canceled = SubmitOk();
  const uint64_t completed = SubmitOk();
  const uint64_t queued = SubmitOk();
  ASSERT_EQ(store_->ClaimNext()->id, canceled);
  ASSERT_TRUE(store_->RecordFrame(canceled, 0, 48, 0));
  ASSERT_TRUE(store_->Cancel(canceled));
  ASSERT_EQ(store_->ClaimNext()->id, completed);
  ASSERT_TRUE(store_->Complete(completed, json::object()));
  const std::string retry = "/api/v1/jobs/" + std::to_string(canceled) + "/retry";
  httplib::Result result = client_->Post(retry.c_str());
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  const json job = json::parse(result->body);
  EXPECT_EQ(job["id"], canceled);
  EXPECT_EQ(job["state"], "queued");
  EXPECT_TRUE(job["finished_at"].is_null());
  EXPECT_EQ(job["frames"]["done"], 1);  // kept
  EXPECT_EQ(job["traced_per_frame"][0], 48);
  json error = ExpectError(client_->Post(retry.c_str()), 409, "job_not_retryable");
  EXPECT_EQ(error["message"], "job " + std::to_string(canceled) + " is queued; only failed or canceled jobs can be retried");
  ExpectError(client_->Post(("/api/v1/jobs/" + std::to_string(completed) + "/retry").c_str()), 409, "job_not_retryable");
  ExpectError(client_->Post(("/api/v1/jobs/" + std::to_string(queued) + "/retry").c_str()), 409, "job_not_retryable");
  ExpectError(client_->Post("/api/v1/jobs/999/retry"), 404, "job_not_found");
  ExpectError(client_->Post("/api/v1/jobs/-1/retry"), 400, "invalid_parameter");
}

TEST_F(ApiServerTest, PatchChangesPriorityAndNameAndTellsTheFarm) {
  const uint64_t id = SubmitOk();
  const std::string path = "/api/v1/jobs/" + std::to_string(id);
  auto patch = [&](const std::string& body) { return client_->Patch(path.c_str(), body, "application/json"); };
  httplib::Result result = patch(R"({"priority": -50})");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(json::parse(result->body)["priority"], -50);
  EXPECT_EQ(farm_.Priorities(), (std::vector<std::pair<uint64_t, int>>{{id, -50}}));
  result = patch(R"({"name": "shot 12", "priority": 100})");
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(json::parse(result->body)["name"], "shot 12");
  EXPECT_EQ(store_->Get(id)->spec.priority, 100);
  result = patch(R"({"name": "renamed only"})");
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(farm_.Priorities().size(), 2u);  // no priority given: the farm is not bothered
  // 200 characters of two bytes each is a name; 201 is not.
  std::string accented;
  for (int i = 0; i < 200; ++i) accented += "\xc3\xa9";
  EXPECT_EQ(patch(json{{"name", accented}}.dump())->status, 200);
  ExpectBadField(patch(json{{"name", accented + "e"}}.dump()), "invalid_field", "/name", "201 characters");
  // A finished job can still be renamed.
  ASSERT_TRUE(store_->Cancel(id));
  EXPECT_EQ(patch(R"({"name": "kept for the record"})")->status, 200);

  ExpectBadField(patch(R"({"priority": 101})"), "invalid_field", "/priority", "expected an integer in [-100, 100]");
  ExpectBadField(patch(R"({"priority": -101})"), "invalid_field", "/priority");
  ExpectBadField(patch(R"({"priority": 1.5})"), "invalid_field", "/priority", "not an integer");
  ExpectBadField(patch(R"({"priority": "5"})"), "invalid_field", "/priority");
  ExpectBadField(patch(R"({"name": ""})"), "invalid_field", "/name", "empty");
  ExpectBadField(patch(R"({"name": 7})"), "invalid_field", "/name", "not a string");
  ExpectBadField(patch(R"({"name": "a", "colour": "red"})"), "unknown_field", "/colour", "priority, name");
  ExpectBadField(patch(R"({"priority": 1, "priority": 2})"), "invalid_json", "/priority", "duplicate");
  ExpectBadField(patch("{}"), "missing_field", "", "changes nothing");
  ExpectBadField(patch("[1]"), "invalid_field", "");
  ExpectError(patch("{\"priority\": "), 400, "invalid_json");
  ExpectError(patch(""), 400, "invalid_json");
  ExpectError(client_->Patch("/api/v1/jobs/999", R"({"priority": 1})", "application/json"), 404, "job_not_found");
  ExpectError(client_->Patch("/api/v1/jobs/1x", R"({"priority": 1})", "application/json"), 400, "invalid_parameter");
  EXPECT_EQ(store_->Get(id)->spec.name, "kept for the record");
}

TEST_F(ApiServerTest, DeleteRemovesAFinishedJobItsFilesAndItsUnsharedAssets) {
  const std::string mine = PutAssetOk(kTriangleObj);
  const std::string shared = PutAssetOk("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  json body = Submission(SceneWithMeshFile("tri.obj"));
  body["scene"]["shapes"].push_back({{"type", "mesh"}, {"file", "other.obj"}});
  body["assets"] = {{"tri.obj", mine}, {"other.obj", shared}};
  const uint64_t id = SubmitOk(body);
  body = Submission(SceneWithMeshFile("other.obj"));
  body["assets"] = {{"other.obj", shared}};
  const uint64_t keeper = SubmitOk(body);
  const std::string path = "/api/v1/jobs/" + std::to_string(id);
  // Queued or running: the job must be canceled first.
  json error = ExpectError(client_->Delete(path.c_str()), 409, "job_active");
  EXPECT_EQ(error["message"], "job " + std::to_string(id) + " is queued; cancel it first (POST " + path +
                                  "/cancel), then delete it");
  ASSERT_TRUE(store_->Cancel(id));
  fs::create_directories(FramePath(id, 0, "exr").parent_path());
  std::ofstream(FramePath(id, 0, "exr")) << std::string(1000, 'f');
  std::ofstream(FramePath(id, 0, "png")) << std::string(100, 'p');

  farm_.Stop();  // a coordinator on its way out deletes nothing
  ExpectError(client_->Delete(path.c_str()), 503, "shutting_down");
  EXPECT_TRUE(fs::exists(FramePath(id, 0, "exr")));
  EXPECT_TRUE(store_->Get(id).has_value());
  farm_.Resume();

  httplib::Result result = client_->Delete(path.c_str());
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(json::parse(result->body),
            (json{{"deleted", id}, {"freed_bytes", 1000 + 100 + kTriangleObj.size()}}));
  EXPECT_FALSE(fs::exists(folder_ / "store" / std::to_string(id)));
  EXPECT_FALSE(fs::exists(folder_ / "store" / "assets" / mine));
  EXPECT_TRUE(fs::exists(folder_ / "store" / "assets" / shared));  // the other job names it
  EXPECT_EQ(farm_.Released(), (std::vector<uint64_t>{id, id}));
  ExpectError(Get(path), 404, "job_not_found");
  ExpectError(Get(path + "/frames/0.exr"), 404, "job_not_found");
  ExpectError(client_->Delete(path.c_str()), 404, "job_not_found");
  ExpectError(client_->Delete("/api/v1/jobs/abc"), 400, "invalid_parameter");
  const std::string metrics = Get("/metrics")->body;
  EXPECT_NE(metrics.find("\ntcfarm_jobs_deleted_total 1"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("\ntcfarm_store_bytes "), std::string::npos) << metrics;
  EXPECT_TRUE(store_->Get(keeper).has_value());
}

// Deleted by the retention (another janitor: the server never heard of it), after a frame
// of the job was served: the job is gone, not its frame "not ready".
TEST_F(ApiServerTest, AJobDeletedBehindTheServersBackIsNotFound) {
  const uint64_t id = SubmitOk();
  ASSERT_TRUE(store_->Cancel(id));
  fs::create_directories(FramePath(id, 3, "exr").parent_path());
  std::ofstream(FramePath(id, 3, "exr")) << "exr";
  ASSERT_EQ(Get("/api/v1/jobs/" + std::to_string(id) + "/frames/3.exr")->status, 200);
  StoreJanitor retention(*store_, folder_ / "store", [](uint64_t) { return true; }, nullptr);
  ASSERT_EQ(retention.Delete(id, "by the retention").outcome, DeletedJob::Outcome::kDeleted);
  for (const char* file : {"3.exr", "3.png", "3/mask.png"}) {
    ExpectError(Get("/api/v1/jobs/" + std::to_string(id) + "/frames/" + std::string(file)), 404, "job_not_found");
  }
}

TEST_F(ApiServerTest, FramesAnswerEachFramesState) {
  const uint64_t id = SubmitOk();  // frames 0..9
  ASSERT_TRUE(store_->ClaimNext());
  ASSERT_TRUE(store_->RecordFrame(id, 0, 48, 0));
  ASSERT_TRUE(store_->RecordFrame(id, 1, 5, 43));
  FarmSnapshot snapshot;
  snapshot.tracingFrames[id] = {1, 2, 3};  // 1 is written already: written wins
  farm_.SetSnapshot(snapshot);
  const std::string path = "/api/v1/jobs/" + std::to_string(id) + "/frames";
  httplib::Result result = Get(path);
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  json body = json::parse(result->body);
  EXPECT_EQ(body["job"], id);
  EXPECT_EQ(body["state"], "running");
  ASSERT_EQ(body["frames"].size(), 10u);
  EXPECT_EQ(body["frames"][0], (json{{"frame", 0}, {"state", "written"}, {"traced", 48}, {"copied", 0}}));
  EXPECT_EQ(body["frames"][1], (json{{"frame", 1}, {"state", "written"}, {"traced", 5}, {"copied", 43}}));
  EXPECT_EQ(body["frames"][2], (json{{"frame", 2}, {"state", "tracing"}, {"traced", nullptr}, {"copied", nullptr}}));
  EXPECT_EQ(body["frames"][9]["state"], "queued");
  EXPECT_EQ(body["counts"], (json{{"queued", 6}, {"tracing", 2}, {"written", 2}, {"failed", 0}}));
  // A failed job's unwritten frames failed; a canceled job's would render on a retry.
  ASSERT_TRUE(store_->Fail(id, "broken"));
  body = json::parse(Get(path)->body);
  EXPECT_EQ(body["counts"], (json{{"queued", 0}, {"tracing", 0}, {"written", 2}, {"failed", 8}}));
  ASSERT_TRUE(store_->Retry(id));
  ASSERT_TRUE(store_->Cancel(id));
  EXPECT_EQ(json::parse(Get(path)->body)["counts"]["queued"], 8);
  ExpectError(Get("/api/v1/jobs/999/frames"), 404, "job_not_found");
  ExpectError(Get("/api/v1/jobs/0x1/frames"), 400, "invalid_parameter");
}

TEST_F(ApiServerTest, AJobsEventsComeInOrderAndPageWithAfter) {
  const uint64_t id = SubmitOk();
  const uint64_t other = SubmitOk();
  ASSERT_TRUE(store_->ClaimNext());
  ASSERT_TRUE(store_->Cancel(id));
  const std::string path = "/api/v1/jobs/" + std::to_string(id) + "/events";
  json events = json::parse(Get(path)->body)["events"];
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[0]["type"], "submitted");
  EXPECT_EQ(events[0]["job"], id);
  EXPECT_EQ(events[0]["time"], "2024-05-01T12:34:56.789Z");
  EXPECT_EQ(events[0]["strategy"], "search");
  EXPECT_EQ(events[1]["type"], "started");
  EXPECT_EQ(events[2]["type"], "canceled");
  EXPECT_EQ(events[2]["message"], "canceled with 0 of 10 frames written");
  const uint64_t first = events[0]["seq"].get<uint64_t>();
  json after = json::parse(Get(path + "?after=" + std::to_string(first))->body)["events"];
  ASSERT_EQ(after.size(), 2u);
  EXPECT_EQ(after[0]["type"], "started");
  EXPECT_EQ(json::parse(Get(path + "?limit=1")->body)["events"].size(), 1u);
  EXPECT_EQ(json::parse(Get("/api/v1/jobs/" + std::to_string(other) + "/events")->body)["events"].size(), 1u);
  ExpectError(Get(path + "?after=-3"), 400, "invalid_parameter");
  ExpectError(Get(path + "?limit=10001"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs/999/events"), 404, "job_not_found");
}

// A stream of events read by a real HTTP client: the log replayed from a seq, then what
// happens live; a keepalive when nothing does; a bounded number of streams; and a server
// that stops while streams are open, promptly.
class EventStreamTest : public ApiServerTest {
 protected:
  void SetUp() override {
    ApiServerTest::SetUp();
    ApiOptions options = SecondServerOptions();
    options.maxEventStreams = 2;
    options.eventKeepAlive = std::chrono::milliseconds(200);
    streamServer_ = std::make_unique<ApiServer>(*store_, farm_, std::make_shared<prometheus::Registry>(), options);
    streamPort_ = streamServer_->Start();
  }
  void TearDown() override {
    streamServer_.reset();
    ApiServerTest::TearDown();
  }
  // Reads the stream at `path` until `enough` says the text so far is enough.
  std::string Follow(const std::string& path, const std::function<bool(const std::string&)>& enough,
                     httplib::Headers headers = {}) {
    httplib::Client client("127.0.0.1", streamPort_);
    client.set_read_timeout(10, 0);
    std::string text;
    client.Get(path.c_str(), headers, [&](const char* data, size_t length) {
      text.append(data, length);
      return !enough(text);
    });
    return text;
  }
  static size_t Count(const std::string& text, const std::string& part) {
    size_t count = 0;
    for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++count;
    return count;
  }

  std::unique_ptr<ApiServer> streamServer_;
  int streamPort_ = 0;
};

TEST_F(EventStreamTest, ReplaysFromASeqThenFollowsLive) {
  const uint64_t id = SubmitOk();
  std::thread later([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    store_->Cancel(id);
  });
  const std::string text =
      Follow("/api/v1/events?after=0", [](const std::string& t) { return t.find("event: canceled") != std::string::npos; });
  later.join();
  const uint64_t submitted = store_->Events({id, 0, 10}).at(0).seq;
  const std::string expected = "id: " + std::to_string(submitted) + "\nevent: submitted\ndata: {";
  EXPECT_EQ(text.rfind(expected, 0), 0u) << text;
  const size_t data = text.find("data: ") + 6;
  const json event = json::parse(text.substr(data, text.find('\n', data) - data));
  EXPECT_EQ(event["type"], "submitted");
  EXPECT_EQ(event["seq"], submitted);
  EXPECT_NE(text.find("event: canceled\ndata: "), std::string::npos) << text;

  // Resumed by an EventSource with Last-Event-ID: only what came after it.
  const std::string resumed = Follow("/api/v1/events", [](const std::string& t) { return t.find("\n\n") != std::string::npos; },
                                     {{"Last-Event-ID", std::to_string(submitted)}});
  EXPECT_EQ(resumed.find("event: submitted"), std::string::npos) << resumed;
  EXPECT_NE(resumed.find("event: canceled"), std::string::npos) << resumed;
  // One job only; compression asked for changes nothing (an event stream is never buffered).
  const uint64_t other = SubmitOk();
  const std::string filtered = Follow("/api/v1/events?after=0&job=" + std::to_string(other),
                                      [](const std::string& t) { return t.find("\n\n") != std::string::npos; },
                                      {{"Accept-Encoding", "gzip, deflate"}});
  EXPECT_EQ(filtered.rfind("id: " + std::to_string(store_->Events({other, 0, 10}).at(0).seq) + "\n", 0), 0u)
      << filtered;
  ExpectError(Get("/api/v1/events?after=x"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/events?job=999"), 404, "job_not_found");
  httplib::Client client("127.0.0.1", port_);
  ExpectError(client.Get("/api/v1/events", {{"Last-Event-ID", "yesterday"}}), 400, "invalid_parameter");
}

TEST_F(EventStreamTest, WithoutACursorItStartsWithTheNextEventAndKeepsAlive) {
  SubmitOk();  // before the stream: not replayed
  const std::string text = Follow("/api/v1/events", [](const std::string& t) { return Count(t, ": keepalive\n\n") >= 2; });
  EXPECT_EQ(text, ": keepalive\n\n: keepalive\n\n");
}

TEST_F(EventStreamTest, StreamsAreBoundedAndEndWhenTheServerStops) {
  std::atomic<int> ended{0};
  std::vector<std::thread> followers;
  for (int i = 0; i < 2; ++i) {
    followers.emplace_back([&] {
      Follow("/api/v1/events", [](const std::string&) { return false; });
      ++ended;
    });
  }
  httplib::Client client("127.0.0.1", streamPort_);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const json error = ExpectError(client.Get("/api/v1/events"), 503, "too_many_streams");
  EXPECT_NE(error.value("message", "").find("2 event streams are open"), std::string::npos) << error;
  // Other requests are served meanwhile.
  EXPECT_EQ(client.Get("/api/v1/jobs")->status, 200);
  const auto start = std::chrono::steady_clock::now();
  streamServer_->Stop();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(3));
  for (std::thread& follower : followers) follower.join();
  EXPECT_EQ(ended, 2);
}

// curl -X POST sends neither Content-Length nor Transfer-Encoding: no body, not "read until
// the client closes".
TEST_F(ApiServerTest, PostWithoutAnyLengthHeaderHasAnEmptyBody) {
  const uint64_t id = SubmitOk();
  const std::string answer = RawExchange(
      port_, "POST /api/v1/jobs/" + std::to_string(id) +
                 "/cancel HTTP/1.1\r\nHost: test\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(answer.rfind("HTTP/1.1 200", 0), 0u) << answer;
  EXPECT_EQ(store_->Get(id)->state, JobState::kCanceled);
}

TEST_F(ApiServerTest, CompletedJobCannotBeCanceled) {
  const uint64_t id = SubmitOk();
  ASSERT_TRUE(store_->ClaimNext());
  ASSERT_TRUE(store_->Complete(id, json::object()));
  ExpectError(client_->Post(("/api/v1/jobs/" + std::to_string(id) + "/cancel").c_str()), 409,
              "job_finished");
  EXPECT_TRUE(farm_.Canceled().empty());
}

// --- frames ------------------------------------------------------------------------------

TEST_F(ApiServerTest, FrameFilesComeBackByteForByte) {
  const uint64_t id = SubmitOk();
  fs::create_directories(FramePath(id, 3, "png").parent_path());
  std::string png("\x89PNG\r\n\x1a\n", 8);
  for (int i = 0; i < 200000; ++i) png += static_cast<char>(i * 7 % 256);  // several chunks
  std::ofstream(FramePath(id, 3, "png"), std::ios::binary) << png;
  const std::string exr = "v/1\x01 not really an exr";
  std::ofstream(FramePath(id, 3, "exr"), std::ios::binary) << exr;

  httplib::Result result = Get("/api/v1/jobs/" + std::to_string(id) + "/frames/3.png");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(result->get_header_value("Content-Type"), "image/png");
  EXPECT_TRUE(result->body == png);

  result = Get("/api/v1/jobs/" + std::to_string(id) + "/frames/3.exr");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200);
  EXPECT_EQ(result->get_header_value("Content-Type"), "image/x-exr");
  EXPECT_EQ(result->body, exr);
}

// A frame whose preview is not made yet (its job renders, or the farm has not been idle
// since) gets one on request, from its EXR, kept for the next request.
TEST_F(ApiServerTest, APreviewIsMadeFromTheExrWhenAskedBeforeItIsWritten) {
  const uint64_t id = SubmitOk();
  fs::create_directories(FramePath(id, 2, "exr").parent_path());
  Image frame{4, 2, std::vector<float>(24, 0.0f)};
  frame.rgb[0] = 1.0f;  // the top left pixel red
  WriteExr(FramePath(id, 2, "exr"), frame, "none");
  httplib::Result result = Get("/api/v1/jobs/" + std::to_string(id) + "/frames/2.png");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(result->get_header_value("Content-Type"), "image/png");
  ASSERT_TRUE(fs::exists(FramePath(id, 2, "png")));
  const Image preview = ReadImage(FramePath(id, 2, "png"));
  EXPECT_EQ(preview.width, 4);
  EXPECT_FLOAT_EQ(preview.rgb[0], 1.0f);
  EXPECT_FLOAT_EQ(preview.rgb[3], 0.0f);
  std::ifstream kept(FramePath(id, 2, "png"), std::ios::binary);
  EXPECT_EQ(result->body, std::string(std::istreambuf_iterator<char>(kept), std::istreambuf_iterator<char>()));
}

TEST_F(ApiServerTest, FrameErrors) {
  const uint64_t id = SubmitOk();
  const std::string frames = "/api/v1/jobs/" + std::to_string(id) + "/frames/";
  ExpectError(Get(frames + "4.png"), 404, "frame_not_ready");
  ExpectError(Get(frames + "10.png"), 400, "invalid_parameter");
  ExpectError(Get(frames + "4.jpg"), 400, "invalid_parameter");
  ExpectError(Get(frames + "4"), 400, "invalid_parameter");
  ExpectError(Get(frames + "-1.png"), 400, "invalid_parameter");
  ExpectError(Get(frames + "..%2F..%2Fjobs.sqlite"), 404, "not_found");
  ExpectError(Get(frames + "%2e%2e.png"), 400, "invalid_parameter");
  ExpectError(Get("/api/v1/jobs/99/frames/0.png"), 404, "job_not_found");
}

TEST_F(ApiServerTest, MaskFilesAndTheirErrors) {
  const uint64_t id = SubmitOk();
  const fs::path folder = FramePath(id, 3, "png").parent_path();
  fs::create_directories(folder);
  std::ofstream(folder / (MaskFileStem("mask", 3) + ".png"), std::ios::binary) << "traced";
  std::ofstream(folder / (MaskFileStem("change", 3) + ".png"), std::ios::binary) << "changed";
  const std::string frames = "/api/v1/jobs/" + std::to_string(id) + "/frames/";

  httplib::Result result = Get(frames + "3/mask.png");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(result->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(result->body, "traced");
  result = Get(frames + "3/change.png");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  EXPECT_EQ(result->body, "changed");

  ExpectError(Get(frames + "4/mask.png"), 404, "frame_not_ready");
  ExpectError(Get(frames + "4/change.png"), 404, "frame_not_ready");
  ExpectError(Get(frames + "10/mask.png"), 400, "invalid_parameter");
  ExpectError(Get(frames + "x/mask.png"), 400, "invalid_parameter");
  ExpectError(Get(frames + "3.png/mask.png"), 400, "invalid_parameter");
  ExpectError(Get(frames + "3/other.png"), 404, "not_found");
  ExpectError(Get("/api/v1/jobs/99/frames/0/mask.png"), 404, "job_not_found");
}

// --- workers, health, metrics, routing -------------------------------------------------

TEST_F(ApiServerTest, WorkersComeFromTheFarmSnapshot) {
  FarmSnapshot snapshot;
  WorkerSnapshot worker;
  worker.name = "node-1/4242";
  worker.principal = "key:rq:rn+=Dq:[!z*gHrFd2kXr!DYIQTrOnH/IJ-r";
  worker.capacity = 4;
  worker.threads = 16;
  worker.inFlight = 3;
  worker.tasksDone = 120;
  worker.pixelsDone = 99999;
  worker.traceSeconds = 12.5;
  worker.secondsSinceHeard = 0.25;
  worker.connectedSeconds = 60;
  snapshot.workers.push_back(worker);
  snapshot.queuedTasks = 7;
  snapshot.inFlightTasks = 3;
  farm_.SetSnapshot(snapshot);

  httplib::Result result = Get("/api/v1/workers");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200);
  EXPECT_EQ(json::parse(result->body),
            (json{{"workers",
                   {{{"name", "node-1/4242"}, {"principal", "key:rq:rn+=Dq:[!z*gHrFd2kXr!DYIQTrOnH/IJ-r"},
                     {"capacity", 4}, {"threads", 16}, {"in_flight", 3},
                     {"tasks_done", 120}, {"pixels_done", 99999}, {"trace_seconds", 12.5},
                     {"seconds_since_heard", 0.25}, {"connected_seconds", 60.0}}}},
                  {"queued_tasks", 7},
                  {"in_flight_tasks", 3}}));
}

// ?distrusted lists the bans; lifting one is an admin's right, a principal given once,
// and an unknown one is a 404. A CURVE key may hold '/': it travels as a query value.
TEST_F(ApiServerTest, DistrustedWorkersAreListedAndTheirBansLifted) {
  const std::string principal = "key:rq:rn+=Dq:[!z*gHrFd2kXr!DYIQTrOnH/IJ-r";
  farm_.Ban({principal, "liar", "grey pixels", kNowMs});
  httplib::Result listed = Get("/api/v1/workers?distrusted");
  ASSERT_TRUE(listed);
  ASSERT_EQ(listed->status, 200);
  const json bans = json::parse(listed->body)["distrusted"];
  ASSERT_EQ(bans.size(), 1u);
  EXPECT_EQ(bans[0]["principal"], principal);
  EXPECT_EQ(bans[0]["why"], "grey pixels");
  EXPECT_EQ(bans[0]["banned_at"], "2024-05-01T12:34:56.789Z");
  httplib::Result missing = client_->Delete("/api/v1/workers/distrusted");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 400);
  const std::string query = "/api/v1/workers/distrusted?principal=" + httplib::detail::encode_query_param(principal);
  httplib::Result lifted = client_->Delete(query.c_str());
  ASSERT_TRUE(lifted);
  EXPECT_EQ(lifted->status, 200) << lifted->body;
  EXPECT_EQ(json::parse(lifted->body)["lifted"], principal);
  EXPECT_TRUE(farm_.Bans().empty());
  httplib::Result again = client_->Delete(query.c_str());
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 404);
  EXPECT_EQ(json::parse(again->body)["error"]["code"], "ban_not_found");
}

// The strategies clients offer are the coordinator's own list, in its order.
TEST_F(ApiServerTest, ListsTheStrategiesItAccepts) {
  httplib::Result result = Get("/api/v1/strategies");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 200);
  json names = json::array();
  for (const StrategyNameEntry& entry : kStrategyNames) names.push_back(std::string(entry.name));
  EXPECT_EQ(json::parse(result->body), (json{{"strategies", names}, {"default", "search"}}));
}

TEST_F(ApiServerTest, Healthz) {
  httplib::Result result = Get("/healthz");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 200);
  EXPECT_EQ(json::parse(result->body), (json{{"status", "ok"}}));
}

TEST_F(ApiServerTest, UnknownRouteIs404AndWrongMethodIs405) {
  ExpectError(Get("/api/v2/jobs"), 404, "not_found");
  ExpectError(Get("/"), 404, "not_found");
  ExpectError(client_->Delete("/nothing/here"), 404, "not_found");

  httplib::Result wrong = client_->Put("/api/v1/jobs/1", "{}", "application/json");
  ExpectError(wrong, 405, "method_not_allowed");
  EXPECT_EQ(wrong->get_header_value("Allow"), "GET, HEAD, PATCH, DELETE");
  ExpectError(Get("/api/v1/jobs/1/retry"), 405, "method_not_allowed");
  ExpectError(Post("/api/v1/events", json::object()), 405, "method_not_allowed");
  wrong = client_->Put("/api/v1/jobs", "{}", "application/json");
  ExpectError(wrong, 405, "method_not_allowed");
  EXPECT_EQ(wrong->get_header_value("Allow"), "POST, GET, HEAD");
  ExpectError(Get("/api/v1/jobs/1/cancel"), 405, "method_not_allowed");
  ExpectError(Post("/healthz", json::object()), 405, "method_not_allowed");

  httplib::Result options = client_->Options("/api/v1/workers");
  ASSERT_TRUE(options);
  EXPECT_EQ(options->status, 204);
  EXPECT_EQ(options->get_header_value("Allow"), "GET, HEAD");
}

// Every operation the spec describes is served: a route group the server leaves out, or a
// route its group leaves out, would be missing from the Allow of its path.
TEST_F(ApiServerTest, ServesEveryOperationTheSpecDescribes) {
  std::ifstream in(kOpenApiSpec);
  ASSERT_TRUE(in) << kOpenApiSpec;
  const std::regex pathLine("  (/[^ :]*):");
  const std::regex operationLine("    (get|post|put|patch|delete):");
  std::string path;  // the current path of the spec's `paths`, with its parameters filled in
  size_t operations = 0;
  for (std::string line; std::getline(in, line);) {
    std::smatch match;
    if (!line.empty() && line[0] != ' ') {
      path.clear();  // a top-level key: outside `paths` until the next path
    } else if (std::regex_match(line, match, pathLine)) {
      path = std::regex_replace(match[1].str(), std::regex("\\{(id|frame)\\}"), "1");
      path = std::regex_replace(path, std::regex("\\{sha256\\}"), std::string(64, '0'));
    } else if (!path.empty() && std::regex_match(line, match, operationLine)) {
      std::string method = match[1];
      std::transform(method.begin(), method.end(), method.begin(),
                     [](char c) { return static_cast<char>(std::toupper(static_cast<unsigned char>(c))); });
      httplib::Result options = client_->Options(path.c_str());
      ASSERT_TRUE(options) << path;
      EXPECT_EQ(options->status, 204) << path;
      const std::string allowed = ", " + options->get_header_value("Allow") + ",";
      EXPECT_NE(allowed.find(" " + method + ","), std::string::npos)
          << method << " " << path << ": Allow is \"" << options->get_header_value("Allow") << "\"";
      ++operations;
    }
  }
  EXPECT_GE(operations, 20u) << "the spec's paths were not all read";
}

TEST_F(ApiServerTest, MetricsPassPromtool) {
  httplib::Result result = Get("/metrics");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200);
  EXPECT_EQ(result->get_header_value("Content-Type"), "text/plain; version=0.0.4");
  EXPECT_NE(result->body.find("tcfarm_test_renders_total{strategy=\"search\"} 3"), std::string::npos)
      << result->body;

  const char* promtool = "/usr/bin/promtool";
  TCFARM_REQUIRE_TOOL(fs::exists(promtool), "no " << promtool);
  const fs::path text = folder_ / "metrics.txt";
  std::ofstream(text, std::ios::binary) << result->body;
  int status = 0;
  const std::string output =
      RunCommand(std::string(promtool) + " check metrics < '" + text.string() + "' 2>&1", &status);
  EXPECT_EQ(status, 0) << output;
}

TEST_F(ApiServerTest, ConcurrentClientsSeeConsistentJobs) {
  constexpr int kThreads = 4;
  constexpr int kJobsPerThread = 5;
  std::vector<std::thread> threads;
  std::atomic<int> created{0};
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([this, &created] {
      httplib::Client client("127.0.0.1", port_);
      for (int i = 0; i < kJobsPerThread; ++i) {
        httplib::Result result = client.Post("/api/v1/jobs", Submission().dump(), "application/json");
        if (result && result->status == 201) ++created;
        client.Get("/api/v1/jobs?limit=5");
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(created.load(), kThreads * kJobsPerThread);
  EXPECT_EQ(json::parse(Get("/api/v1/jobs?limit=1000")->body).at("jobs").size(),
            static_cast<size_t>(kThreads * kJobsPerThread));
}

TEST(ApiServerStartTest, BusyPortThrowsNamingTheAddress) {
  const fs::path file = fs::temp_directory_path() /
                        ("tcfarm_api_busy_" + std::to_string(std::random_device()()) + ".sqlite");
  {
    JobStore store(file);
    FakeFarm farm;
    ApiOptions options;
    options.host = "127.0.0.1";
    options.port = 0;
    ApiServer first(store, farm, nullptr, options);
    options.port = first.Start();
    ApiServer second(store, farm, nullptr, options);
    try {
      second.Start();
      ADD_FAILURE() << "second server started on a taken port";
    } catch (const std::runtime_error& error) {
      EXPECT_EQ(std::string(error.what()), "cannot listen on 127.0.0.1:" + std::to_string(options.port));
    }
    first.Stop();
    first.Stop();  // twice is harmless
  }
  fs::remove(file);
}

TEST(ApiServerStartTest, DashboardFilesAreServedAtTheRootBesideTheApi) {
  const fs::path folder =
      fs::temp_directory_path() / ("tcfarm_api_dashboard_" + std::to_string(std::random_device()()));
  fs::create_directories(folder / "web");
  std::ofstream(folder / "web" / "index.html") << "<html>tcfarm</html>";
  {
    JobStore store(folder / "jobs.sqlite");
    FakeFarm farm;
    ApiOptions options;
    options.host = "127.0.0.1";
    options.port = 0;
    options.dashboardDirectory = folder / "web";
    ApiServer server(store, farm, nullptr, options);
    httplib::Client client("127.0.0.1", server.Start());
    httplib::Result page = client.Get("/");
    ASSERT_TRUE(page);
    EXPECT_EQ(page->status, 200);
    EXPECT_EQ(page->body, "<html>tcfarm</html>");
    httplib::Result health = client.Get("/healthz");
    ASSERT_TRUE(health);
    EXPECT_EQ(health->status, 200);
    ExpectError(client.Get("/missing.js"), 404, "not_found");

    options.dashboardDirectory = folder / "no-such-folder";
    ApiServer broken(store, farm, nullptr, options);
    EXPECT_THROW(broken.Start(), std::runtime_error);
  }
  fs::remove_all(folder);
}

// --- the OpenAPI contract ------------------------------------------------------------------

TEST(OpenApiSpecTest, IsValidOpenApi) {
  ASSERT_TRUE(fs::exists(kOpenApiSpec)) << kOpenApiSpec;
  const std::string python = PythonWith("openapi_spec_validator");
  TCFARM_REQUIRE_TOOL(!python.empty(), "no python with openapi_spec_validator");
  int status = 0;
  const std::string output =
      RunCommand("'" + python + "' -m openapi_spec_validator '" + kOpenApiSpec.string() + "' 2>&1",
                 &status);
  EXPECT_EQ(status, 0) << output;
}

// checks: [schema name, response body] pairs, each validated against the spec's schema.
void ExpectMatchesSchemas(const std::string& python, const fs::path& folder, const json& checks) {
  const fs::path instances = folder / "instances.json";
  std::ofstream(instances) << checks.dump();
  const fs::path script = folder / "check.py";
  std::ofstream(script) << R"(import json, sys, yaml
from openapi_schema_validator import OAS30Validator
spec = yaml.safe_load(open(sys.argv[1]))
failures = 0
for name, instance in json.load(open(sys.argv[2])):
    schema = {"$ref": "#/components/schemas/" + name, "components": spec["components"]}
    for error in OAS30Validator(schema).iter_errors(instance):
        failures += 1
        print(name, list(error.absolute_path), error.message)
sys.exit(1 if failures else 0)
)";
  int status = 0;
  const std::string output = RunCommand(
      "'" + python + "' '" + script.string() + "' '" + kOpenApiSpec.string() + "' '" +
          instances.string() + "' 2>&1",
      &status);
  EXPECT_EQ(status, 0) << output;
}

// Every response body the server writes must match its schema in the spec, so the spec
// cannot drift from the code unnoticed (the schemas forbid unlisted properties).
TEST_F(ApiServerTest, ResponsesMatchTheOpenApiSchemas) {
  const std::string python = PythonWith("yaml, openapi_schema_validator");
  TCFARM_REQUIRE_TOOL(!python.empty(), "no python with yaml and openapi_schema_validator");
  const uint64_t running = SubmitOk();  // the oldest: ClaimNext takes it
  const uint64_t queued = SubmitOk();
  const uint64_t failed = SubmitOk();
  ASSERT_TRUE(store_->Fail(failed, "no worker can hold it"));
  ASSERT_EQ(store_->ClaimNext()->id, running);
  ASSERT_TRUE(store_->RecordFrame(running, 0, 10, 38));
  FarmSnapshot snapshot;
  snapshot.runningStats[running] = json{{"bins_done", 0}};
  WorkerSnapshot worker;
  worker.name = "w";
  snapshot.workers.push_back(worker);
  farm_.SetSnapshot(snapshot);

  json checks = json::array();
  auto add = [&checks](const std::string& schema, const httplib::Result& result) {
    ASSERT_TRUE(result);
    checks.push_back({schema, json::parse(result->body)});
  };
  add("Job", Get("/api/v1/jobs/" + std::to_string(queued)));
  add("Job", Get("/api/v1/jobs/" + std::to_string(running)));
  add("Job", Get("/api/v1/jobs/" + std::to_string(failed)));
  add("Job", client_->Post(("/api/v1/jobs/" + std::to_string(queued) + "/cancel").c_str()));
  add("JobList", Get("/api/v1/jobs"));
  add("WorkerList", Get("/api/v1/workers"));
  add("Health", Get("/healthz"));
  add("StrategyList", Get("/api/v1/strategies"));
  add("Error", Post("/api/v1/jobs", json{{"scene", 1}}));
  add("Error", Get("/api/v1/jobs/555"));
  add("Error", Get("/nowhere"));
  add("Error", client_->Delete("/api/v1/jobs"));
  json tooLarge = Submission();
  tooLarge["name"] = std::string(kMaxBodyBytes, 'x');
  add("Error", Post("/api/v1/jobs", tooLarge));
  const std::string asset = wire::Sha256Hex(kTriangleObj);
  add("AssetStored", client_->Put(("/api/v1/assets/" + asset).c_str(), kTriangleObj, "application/octet-stream"));
  add("AssetStored", client_->Put(("/api/v1/assets/" + asset).c_str(), kTriangleObj, "application/octet-stream"));
  add("Error", client_->Put(("/api/v1/assets/" + asset).c_str(), "other", "application/octet-stream"));
  add("MissingAssets", Post("/api/v1/assets/missing", json{{"hashes", {asset, wire::Sha256Hex("")}}}));
  json withAssets = Submission(SceneWithMeshFile("tri.obj"));
  withAssets["assets"] = {{"tri.obj", asset}};
  add("Job", Post("/api/v1/jobs", withAssets));
  add("SceneCheck", Post("/api/v1/scenes/check", withAssets));
  withAssets["assets"] = {{"tri.obj", wire::Sha256Hex("not uploaded")}};
  add("SceneCheck", Post("/api/v1/scenes/check", withAssets));
  withAssets["assets"] = {{"tri.obj", wire::Sha256Hex("")}, {"../x", asset}};
  add("Error", Post("/api/v1/jobs", withAssets));
  add("Error", Post("/api/v1/scenes/check", withAssets));

  const std::string failedPath = "/api/v1/jobs/" + std::to_string(failed);
  add("JobList", Get("/api/v1/jobs?state=failed,queued&offset=1&limit=2&name=&strategy=search"));
  add("Job", client_->Patch(failedPath.c_str(), R"({"priority": -5, "name": "x"})", "application/json"));
  add("Error", client_->Patch(failedPath.c_str(), R"({"priority": -500})", "application/json"));
  add("FrameStates", Get("/api/v1/jobs/" + std::to_string(running) + "/frames"));
  add("FrameStates", Get(failedPath + "/frames"));
  add("EventList", Get("/api/v1/jobs/" + std::to_string(running) + "/events"));
  add("Error", client_->Delete(("/api/v1/jobs/" + std::to_string(running)).c_str()));
  add("Error", client_->Post(("/api/v1/jobs/" + std::to_string(running) + "/retry").c_str()));
  add("Job", client_->Post((failedPath + "/retry").c_str()));
  ASSERT_TRUE(store_->Cancel(failed));
  add("Deleted", client_->Delete(failedPath.c_str()));

  ExpectMatchesSchemas(python, folder_, checks);
}

// --- the import budget -------------------------------------------------------------------

// A second server whose scene checks and submits import within a budget the test holds.
class ApiServerWithImportBudgetTest : public ApiServerTest {
 protected:
  static constexpr uint64_t kBudgetBytes = uint64_t{4} << 20;

  void StartServer(std::chrono::milliseconds wait) {
    budget_ = std::make_shared<ImportBudget>(kBudgetBytes, wait);
    ApiOptions options = SecondServerOptions();
    options.importBudget = budget_;
    budgetRegistry_ = std::make_shared<prometheus::Registry>();
    budgetServer_ = std::make_unique<ApiServer>(*store_, farm_, budgetRegistry_, options);
    budgetClient_ = std::make_unique<httplib::Client>("127.0.0.1", budgetServer_->Start());
  }
  void TearDown() override {
    budgetClient_.reset();
    budgetServer_.reset();
    ApiServerTest::TearDown();
  }
  httplib::Result Check(const json& body) {
    return budgetClient_->Post("/api/v1/scenes/check", body.dump(), "application/json");
  }

  std::shared_ptr<ImportBudget> budget_;
  std::shared_ptr<prometheus::Registry> budgetRegistry_;
  std::unique_ptr<ApiServer> budgetServer_;
  std::unique_ptr<httplib::Client> budgetClient_;
};

TEST_F(ApiServerWithImportBudgetTest, ABudgetInUseAnswers503WithRetryAfterAndNothingStored) {
  StartServer(std::chrono::milliseconds(100));
  std::optional<ImportReservation> othersImports = budget_->Reserve(kBudgetBytes);
  const json error = ExpectError(Check(Submission()), 503, "import_busy");
  EXPECT_FALSE(error.contains("pointer"));
  EXPECT_NE(error.value("message", "").find("imports running now hold 4.0 MiB of its 4.0 MiB"), std::string::npos)
      << error.dump();
  httplib::Result submitted = budgetClient_->Post("/api/v1/jobs", Submission().dump(), "application/json");
  ExpectError(submitted, 503, "import_busy");
  ASSERT_TRUE(submitted);
  EXPECT_EQ(submitted->get_header_value("Retry-After"), "1");
  EXPECT_EQ(store_->Query(JobQuery{}).total, 0u);
  EXPECT_EQ(budget_->Stats().refusals, 2u);
  const std::string python = PythonWith("yaml, openapi_schema_validator");
  if (!python.empty()) ExpectMatchesSchemas(python, folder_, json::array({{"Error", json{{"error", error}}}}));

  othersImports.reset();
  httplib::Result checked = Check(Submission());
  ASSERT_TRUE(checked);
  EXPECT_EQ(checked->status, 200) << checked->body;
  EXPECT_FALSE(checked->has_header("Retry-After"));
  EXPECT_EQ(budget_->Stats().reservedBytes, 0u);
}

TEST_F(ApiServerWithImportBudgetTest, ACheckWaitsForAnotherImportToEnd) {
  StartServer(std::chrono::milliseconds(5000));
  auto othersImports = std::make_unique<ImportReservation>(budget_->Reserve(kBudgetBytes));
  std::thread ending([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    othersImports.reset();
  });
  httplib::Result checked = Check(Submission());
  ending.join();
  ASSERT_TRUE(checked);
  EXPECT_EQ(checked->status, 200) << checked->body;
  EXPECT_EQ(budget_->Stats().waits, 1u);
  EXPECT_EQ(budget_->Stats().refusals, 0u);
}

TEST_F(ApiServerWithImportBudgetTest, AnImportLargerThanTheWholeBudgetIs413AtOnce) {
  StartServer(std::chrono::milliseconds(5000));
  // Inline meshes of 100,000 vertices: their document alone takes more than 4 MiB.
  json scene = SmallScene();
  json vertices = json::array(), triangles = json::array();
  for (int v = 0; v < 100000; ++v) vertices.push_back({v % 7, v % 11, v % 13});
  for (int t = 0; t + 2 < 100000; t += 3) triangles.push_back({t, t + 1, t + 2});
  scene["shapes"].push_back({{"type", "mesh"}, {"vertices", vertices}, {"triangles", triangles}});
  const auto start = std::chrono::steady_clock::now();
  const json error = ExpectError(Check(Submission(scene)), 413, "import_too_large");
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(4));  // no wait for room that cannot come
  EXPECT_NE(error.value("message", "").find("more than the import budget of 4.0 MiB holds for all imports together "
                                            "(--import-budget-mib 4); expected a smaller scene"),
            std::string::npos)
      << error.dump();
  EXPECT_EQ(budget_->Stats().reservedBytes, 0u);
}

TEST_F(ApiServerWithImportBudgetTest, MetricsShowTheBudgetAndWhatImportsHold) {
  StartServer(std::chrono::milliseconds(10));
  const ImportReservation held = budget_->Reserve(1 << 20);
  ExpectError(Check(json{{"scene", 1}}), 400, "invalid_scene");
  const std::string text = prometheus::TextSerializer().Serialize(budgetRegistry_->Collect());
  EXPECT_NE(text.find("tcfarm_import_budget_bytes 4194304"), std::string::npos) << text;
  EXPECT_NE(text.find("tcfarm_import_reserved_bytes 1048576"), std::string::npos) << text;
  EXPECT_NE(text.find("tcfarm_import_refusals_total 0"), std::string::npos) << text;
  EXPECT_NE(text.find("tcfarm_import_reserved_peak_bytes"), std::string::npos) << text;
}

// --- API tokens ------------------------------------------------------------------------

const std::string kReadToken = "read-0123456789abcdef";
const std::string kSubmitToken = "submit-0123456789abcdef";
const std::string kOtherSubmitToken = "submit2-0123456789abcdef";
const std::string kAdminToken = "admin-0123456789abcdef";

// The same store and farm behind a second server that has tokens.
class ApiServerWithTokensTest : public ApiServerTest {
 protected:
  void SetUp() override {
    ApiServerTest::SetUp();
    ApiOptions options = SecondServerOptions();
    options.tokens = std::make_shared<const http::ApiTokens>(http::ApiTokens::Parse(
        "read " + kReadToken + "\nsubmit " + kSubmitToken + "\nsubmit " + kOtherSubmitToken + "\nadmin " +
            kAdminToken + "\n",
        "test tokens"));
    tokenServer_ = std::make_unique<ApiServer>(*store_, farm_, std::make_shared<prometheus::Registry>(), options);
    tokenPort_ = tokenServer_->Start();
  }
  void TearDown() override {
    tokenServer_.reset();
    ApiServerTest::TearDown();
  }

  httplib::Client As(const std::string& token) {
    httplib::Client client("127.0.0.1", tokenPort_);
    if (!token.empty()) client.set_bearer_token_auth(token.c_str());
    return client;
  }

  std::unique_ptr<ApiServer> tokenServer_;
  int tokenPort_ = 0;
};

TEST_F(ApiServerWithTokensTest, EveryRouteButHealthzNeedsAKnownToken) {
  for (const char* path : {"/api/v1/jobs", "/api/v1/jobs/1", "/api/v1/workers", "/api/v1/strategies", "/metrics",
                           "/api/v1/jobs/1/frames/0.png", "/api/v1/jobs/1/frames/0/mask.png"}) {
    httplib::Result result = As("").Get(path);
    ExpectError(result, 401, "unauthorized");
    if (result) {
      EXPECT_EQ(result->get_header_value("WWW-Authenticate"), "Bearer realm=\"tcfarm\"") << path;
    }
    ExpectError(As("unknown-0123456789abcdef").Get(path), 401, "unauthorized");
    httplib::Result asReader = As(kReadToken).Get(path);
    ASSERT_TRUE(asReader);
    EXPECT_NE(asReader->status, 401) << path;
    EXPECT_NE(asReader->status, 403) << path;
  }
  ExpectError(As("").Post("/api/v1/jobs", Submission().dump(), "application/json"), 401, "unauthorized");
  ExpectError(As("").Post("/api/v1/assets/missing", "{}", "application/json"), 401, "unauthorized");
  EXPECT_EQ(As("").Get("/healthz")->status, 200);
  // A header that is not "Bearer TOKEN" is no token.
  httplib::Client basic("127.0.0.1", tokenPort_);
  basic.set_basic_auth("admin", kAdminToken.c_str());
  ExpectError(basic.Get("/api/v1/jobs"), 401, "unauthorized");
}

// The header counts as sent, byte for byte: httplib percent-decodes header values, so each
// of these once reached the token check as the read token itself.
TEST_F(ApiServerWithTokensTest, TheAuthorizationHeaderIsTakenByteForByte) {
  const auto statusWith = [this](const std::string& authorization) {
    const std::string answer = RawExchange(tokenPort_, "GET /api/v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: " +
                                                           authorization + "\r\nConnection: close\r\n\r\n");
    return answer.substr(0, answer.find("\r\n"));
  };
  EXPECT_EQ(statusWith("Bearer " + kReadToken), "HTTP/1.1 200 OK");
  ASSERT_EQ(kReadToken[0], 'r');
  for (const std::string& near : {"Bearer " + kReadToken + "%00junk", "Bearer %72" + kReadToken.substr(1),
                                  "Bearer " + kReadToken + "junk", "Bearer " + kReadToken + std::string(1, '\0') + "junk",
                                  "Bearer " + kReadToken + "%20x"}) {
    EXPECT_EQ(statusWith(near), "HTTP/1.1 401 Unauthorized") << near;
  }
  // Two headers: which one would count is a guess, so neither does.
  EXPECT_EQ(statusWith("Bearer " + kReadToken + "\r\nAuthorization: Bearer " + kReadToken),
            "HTTP/1.1 401 Unauthorized");
}

TEST_F(ApiServerWithTokensTest, RolesDecideWhatATokenMayDo) {
  const json readOnly = ExpectError(As(kReadToken).Post("/api/v1/jobs", Submission().dump(), "application/json"),
                                    403, "forbidden");
  EXPECT_NE(readOnly.value("message", "").find("needs a token of role submit"), std::string::npos) << readOnly;
  EXPECT_EQ(readOnly.dump().find(kReadToken), std::string::npos);
  ExpectError(As(kReadToken).Put(("/api/v1/assets/" + wire::Sha256Hex("x")).c_str(), "x", "application/octet-stream"),
              403, "forbidden");
  EXPECT_FALSE(fs::exists(folder_ / "store" / "assets" / wire::Sha256Hex("x")));
  httplib::Result submitted = As(kSubmitToken).Post("/api/v1/jobs", Submission().dump(), "application/json");
  ASSERT_TRUE(submitted);
  ASSERT_EQ(submitted->status, 201) << submitted->body;
  const json job = json::parse(submitted->body);
  EXPECT_EQ(job.value("submitted_by", ""), http::TokenId(kSubmitToken));
  const std::string cancel = "/api/v1/jobs/" + std::to_string(job["id"].get<uint64_t>()) + "/cancel";
  const json notYours = ExpectError(As(kOtherSubmitToken).Post(cancel.c_str()), 403, "forbidden");
  EXPECT_NE(notYours.value("message", "").find(http::TokenId(kSubmitToken)), std::string::npos) << notYours;
  ExpectError(As(kReadToken).Post(cancel.c_str()), 403, "forbidden");
  EXPECT_TRUE(farm_.Canceled().empty());
  EXPECT_EQ(As(kSubmitToken).Post(cancel.c_str())->status, 200);
  const uint64_t other = SubmitOk();  // through the server without tokens: nobody's
  const std::string cancelOther = "/api/v1/jobs/" + std::to_string(other) + "/cancel";
  ExpectError(As(kSubmitToken).Post(cancelOther.c_str()), 403, "forbidden");
  EXPECT_EQ(As(kAdminToken).Post(cancelOther.c_str())->status, 200);
}

// Retry, change and delete need what cancel needs: a submit token for its own jobs, an
// admin token for any; reads of frames and events need a read token.
TEST_F(ApiServerWithTokensTest, RetryChangeAndDeleteNeedWhatCancelNeeds) {
  httplib::Result submitted = As(kSubmitToken).Post("/api/v1/jobs", Submission().dump(), "application/json");
  ASSERT_TRUE(submitted);
  ASSERT_EQ(submitted->status, 201) << submitted->body;
  const uint64_t id = json::parse(submitted->body)["id"].get<uint64_t>();
  ASSERT_TRUE(store_->Cancel(id));
  const std::string path = "/api/v1/jobs/" + std::to_string(id);
  const std::string patch = R"({"priority": 3})";
  for (const std::string& token : {kReadToken, kOtherSubmitToken}) {
    ExpectError(As(token).Post((path + "/retry").c_str()), 403, "forbidden");
    ExpectError(As(token).Patch(path.c_str(), patch, "application/json"), 403, "forbidden");
    ExpectError(As(token).Delete(path.c_str()), 403, "forbidden");
  }
  ExpectError(As("").Delete(path.c_str()), 401, "unauthorized");
  EXPECT_EQ(store_->Get(id)->state, JobState::kCanceled);
  for (const std::string& read : {path + "/frames", path + "/events"}) {
    ExpectError(As("").Get(read.c_str()), 401, "unauthorized");
    EXPECT_EQ(As(kReadToken).Get(read.c_str())->status, 200) << read;
  }
  ExpectError(As("").Get("/api/v1/events"), 401, "unauthorized");
  EXPECT_EQ(As(kSubmitToken).Patch(path.c_str(), patch, "application/json")->status, 200);
  EXPECT_EQ(As(kAdminToken).Post((path + "/retry").c_str())->status, 200);
  ASSERT_TRUE(store_->Cancel(id));
  EXPECT_EQ(As(kSubmitToken).Delete(path.c_str())->status, 200);
  ExpectError(As(kAdminToken).Delete(path.c_str()), 404, "job_not_found");
}

TEST_F(ApiServerWithTokensTest, RefusalsMatchTheOpenApiSchemas) {
  const std::string python = PythonWith("yaml, openapi_schema_validator");
  TCFARM_REQUIRE_TOOL(!python.empty(), "no python with yaml and openapi_schema_validator");
  json checks = json::array();
  auto add = [&checks](const std::string& schema, const httplib::Result& result) {
    ASSERT_TRUE(result);
    checks.push_back({schema, json::parse(result->body)});
  };
  add("Error", As("").Get("/api/v1/jobs"));
  add("Error", As(kReadToken).Post("/api/v1/jobs", Submission().dump(), "application/json"));
  add("Job", As(kSubmitToken).Post("/api/v1/jobs", Submission().dump(), "application/json"));
  add("JobList", As(kReadToken).Get("/api/v1/jobs"));
  ExpectMatchesSchemas(python, folder_, checks);
}

// The spec names exactly the routes the server has.
TEST(OpenApiSpecTest, DescribesEveryRoute) {
  std::ifstream in(kOpenApiSpec);
  ASSERT_TRUE(in) << kOpenApiSpec;
  std::stringstream text;
  text << in.rdbuf();
  for (const char* path : {"/api/v1/jobs:", "/api/v1/jobs/{id}:", "/api/v1/jobs/{id}/cancel:",
                           "/api/v1/jobs/{id}/frames/{frame}.png:", "/api/v1/jobs/{id}/frames/{frame}.exr:",
                           "/api/v1/jobs/{id}/frames/{frame}/mask.png:",
                           "/api/v1/jobs/{id}/frames/{frame}/change.png:",
                           "/api/v1/assets/{sha256}:", "/api/v1/assets/missing:",
                           "/api/v1/jobs/{id}/retry:", "/api/v1/jobs/{id}/frames:", "/api/v1/jobs/{id}/events:",
                           "/api/v1/events:", "/api/v1/workers:", "/api/v1/strategies:", "/healthz:",
                           "/metrics:"}) {
    EXPECT_NE(text.str().find(std::string("\n  ") + path), std::string::npos) << path;
  }
}

// Wherever the spec names the strategies (the submission, the job returned), it lists the
// coordinator's own list, in its order: kStrategyNames is what the server accepts.
TEST(OpenApiSpecTest, ListsTheStrategiesTheServerAccepts) {
  std::ifstream in(kOpenApiSpec);
  ASSERT_TRUE(in) << kOpenApiSpec;
  std::string names;
  for (const StrategyNameEntry& entry : kStrategyNames) {
    names += (names.empty() ? "" : ", ") + std::string(entry.name);
  }
  const std::string expected = "enum: [" + names + "]";
  size_t enums = 0;
  size_t strategyIndent = std::string::npos;  // inside a `strategy:` property while set
  for (std::string line; std::getline(in, line);) {
    const size_t indent = line.find_first_not_of(' ');
    if (indent == std::string::npos) continue;
    const std::string trimmed = line.substr(indent);
    if (strategyIndent != std::string::npos && indent <= strategyIndent) strategyIndent = std::string::npos;
    if (trimmed == "strategy:") {
      strategyIndent = indent;
    } else if (strategyIndent != std::string::npos && trimmed.rfind("enum:", 0) == 0) {
      EXPECT_EQ(trimmed, expected);
      ++enums;
    }
  }
  EXPECT_EQ(enums, 2u) << "the submission's and the job's strategy";
}

}  // namespace
}  // namespace tcfarm
