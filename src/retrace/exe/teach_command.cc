// retrace teach: build a map from one drive.

#include <chrono>
#include <exception>
#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "retrace/camera/camera_checks.h"
#include "retrace/camera/camera_io.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
#include "retrace/exe/commands.h"
#include "retrace/exe/sequence_input.h"
#include "retrace/feature/binary_features.h"
#include "retrace/image/image_utils.h"
#include "retrace/map/map_database.h"
#include "retrace/repeat/map_loading.h"
#include "retrace/repeat/taught_path.h"
#include "retrace/teach/map_report.h"
#include "retrace/teach/teach_settings.h"
#include "retrace/teach/teacher.h"
#include "retrace/util/error.h"
#include "retrace/util/progress.h"
#include "retrace/util/version.h"

namespace retrace {
namespace {

struct TeachArguments {
  std::filesystem::path sequence;
  BagInput bag;
  std::filesystem::path camera;
  std::filesystem::path map;
  std::string method = "tracking";
  int width = 0;
  size_t every = 1;
  size_t offset = 0;
  bool overwrite = false;
  bool append = false;  // add the drive to the existing map as its next route, linked where it sees the same places
  bool no_progress = false;
  double camera_height = 0.0;  // metres above the ground, stored for repeat's metric path (0 = not given)
  TeachOptions options;
  MapDatabaseOptions storage;
  // Store the key-images' relocalization descriptors themselves rather than their differences from the stored
  // key-image's (map/descriptor_coding.h): a larger map whose descriptors need no key-image to be read.
  bool verbatim_descriptors = false;
};

// The camera of the sequence: --camera, else the calibration file found in the sequence's layout (a bag's
// CameraInfo).
std::unique_ptr<CameraModel> LoadCamera(const TeachArguments& args, Sequence& sequence) {
  if (!args.camera.empty()) return ReadCameraFile(args.camera, sequence.image_size(), sequence.calibration_camera());
  std::unique_ptr<CameraModel> camera = SequenceCamera(sequence);
  if (!camera) {
    throw InputError(args.sequence.string(), sequence.layout() == "rosbag"
                                                 ? "no CameraInfo in the bag; give --camera FILE or --camera-topic"
                                                 : "no calibration file in the sequence; give --camera FILE");
  }
  return camera;
}

// Two calibrations that image the same rays within this distance at the key-images' resolution are one camera (as
// in `retrace repeat`).
constexpr double kSameCameraPx = 1.0;

// --append: the camera the map stores (its key-images' camera). Throws InputError naming the map when there is none.
std::unique_ptr<CameraModel> MapCamera(const TeachArguments& args) {
  std::error_code ec;
  if (!std::filesystem::exists(args.map, ec)) throw InputError(args.map.string(), "no such map to append to");
  const std::optional<std::string> yaml = MapDatabase::Open(args.map)->ReadCameraYaml();
  if (!yaml) throw InputError(args.map.string(), "the map stores no camera; cannot append a drive to it");
  return ParseCameraText(*yaml, args.map.string() + " (camera)");
}

// --append: the drive must have been recorded with the map's camera (at the map's key-image width unless --width
// says otherwise). Throws InputError naming the sequence when it was not.
void CheckAppendCamera(const TeachArguments& args, const CameraModel& camera, const CameraModel* map_camera) {
  const bool same_size = map_camera->width() == camera.width() && map_camera->height() == camera.height();
  const double difference = same_size ? CameraProjectionDifferencePx(*map_camera, camera) : 0.0;
  if (!same_size || !(difference <= kSameCameraPx) || camera.model_name() != map_camera->model_name()) {
    throw InputError(
        args.sequence.string(),
        fmt::format("not recorded with the map's camera: {} {}x{} {} vs the map's {} {}x{} {}{}", camera.model_name(),
                    camera.width(), camera.height(), DescribeCameraIntrinsics(camera), map_camera->model_name(),
                    map_camera->width(), map_camera->height(), DescribeCameraIntrinsics(*map_camera),
                    same_size ? fmt::format(" ({:.1f} px apart)", difference) : ""));
  }
}

void RunTeach(const TeachArguments& args) {
  std::unique_ptr<Sequence> sequence = OpenInputSequence(args.sequence, args.bag);
  std::unique_ptr<CameraModel> camera = LoadCamera(args, *sequence);
  if (args.every > 1 || args.offset > 0) {
    sequence = std::make_unique<SubsampledSequence>(std::move(sequence), std::max<size_t>(1, args.every), args.offset);
  }

  // --append: the drive is resized to the map's key-image width (unless --width says otherwise) and must have been
  // recorded with the map's camera; checked before anything is written.
  std::unique_ptr<CameraModel> map_camera = args.append ? MapCamera(args) : nullptr;
  const int width = args.width == 0 && map_camera ? map_camera->width() : args.width;
  double factor = 1.0;
  if (width > 0 && width != camera->width()) {
    factor = static_cast<double>(width) / camera->width();
    camera = camera->Scaled(factor);
  }
  if (map_camera) CheckAppendCamera(args, *camera, map_camera.get());

  // The map is built in <map>.incomplete and moved onto <map> only when teach succeeded (map_database.h); an
  // appended drive is added to a copy of the map there.
  // The key-images' codec error is measured as the tracker will see them (its smoothing, map_database.h).
  MapDatabaseOptions storage = args.storage;
  storage.error_smoothing_px = args.options.smoothing_sigma_px;
  storage.error_reference_width = args.options.reference_width;
  std::unique_ptr<StagedMap> staged =
      args.append ? StagedMap::BeginAppend(args.map) : StagedMap::Begin(args.map, storage, args.overwrite);
  MapDatabase* database = staged->database();
  // The key-images' descriptors are stored as their differences from the stored key-image's own (lossless; on
  // kitti07 a descriptor then costs 4.4 bytes instead of 32).
  if (args.options.store_signatures && !args.verbatim_descriptors) {
    const BinaryFeatureOptions features = args.options.signature_features;
    database->SetDescriptorPrediction([features](const cv::Mat& image, const std::vector<cv::KeyPoint>& keypoints) {
      return DescribeBinaryKeyPoints(image, keypoints, features);
    });
  }
  // The map appended to, with its key-images (the drive is linked to them).
  std::optional<Map> existing;
  if (args.append) existing = database->ReadMap(/*load_images=*/true);
  // On an error the map taught so far stays in <map>.incomplete, marked incomplete; <map> is untouched.
  struct KeptOnError {
    StagedMap& staged;
    ~KeptOnError() {
      if (std::uncaught_exceptions() > 0 && staged.database() != nullptr) {
        spdlog::warn("teach failed: {} is unchanged; the map taught until the error is in {}", staged.path().string(),
                     staged.staging_path().string());
      }
    }
  } kept_on_error{*staged};
  Teacher teacher(*camera, args.options, database);
  // Metadata of an appended drive are kept per route ("route_1_source_sequence", ...); the map's camera and
  // settings stay those of its first teach.
  std::string prefix;
  if (existing) {
    teacher.AppendTo(*existing);
    int route = 0;
    for (const MapNode& node : existing->nodes()) route = std::max(route, node.route + 1);
    prefix = fmt::format("route_{}_", route);
    database->SetMetadata("routes", std::to_string(route + 1));
  }
  database->SetMetadata(prefix + "source_sequence", std::filesystem::absolute(args.sequence).string());
  database->SetMetadata(prefix + "method", args.method);
  database->SetMetadata(prefix + "frames_every", std::to_string(args.every));
  database->SetMetadata(prefix + "frames_offset", std::to_string(args.offset));
  // The camera and what repeat must apply as teach did (teach_settings.h).
  if (!existing) WriteTeachSettings(*camera, args.options, teacher, database, args.camera_height);

  const auto start = std::chrono::steady_clock::now();
  double seconds_reading = 0.0;
  {
    ProgressBar progress("teach", sequence->size(), !args.no_progress);
    while (true) {
      const auto read_start = std::chrono::steady_clock::now();
      std::optional<Frame> frame = sequence->Next();
      if (!frame) break;
      if (factor != 1.0) {
        cv::Mat resized;
        ResizeToWidth(frame->image, camera->width(), &resized);
        frame->image = resized;
      }
      seconds_reading += std::chrono::duration<double>(std::chrono::steady_clock::now() - read_start).count();
      teacher.AddFrame(*frame);
      progress.Advance(1, fmt::format("{} key-images", teacher.statistics().key_images));
    }
    teacher.Finish();
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const TeachStatistics& stats = teacher.statistics();
  const Map& map = teacher.map();
  // A drive that gave no arc (a camera that stood still, or never saw its first key-image's features move by r_p)
  // is no map repeat can use ("the map has no arcs"): say so here, where the cause is known, and replace nothing.
  if (map.arcs().empty() && stats.joins == 0) {
    if (stats.gaps_unrecovered > 0) {
      // Frames were lost to the tracker and not related again by matching: not a camera that stood still.
      throw InputError(args.sequence.string(),
                       fmt::format("teach made no arc from its {} frames: {} times no frame could be tracked or "
                                   "matched to the key-image before it ({}x{} px frames; too small or too blurred "
                                   "to track?); {} not written",
                                   stats.frames, stats.gaps_unrecovered, camera->width(), camera->height(),
                                   args.map.string()));
    }
    throw InputError(args.sequence.string(),
                     fmt::format("teach made no arc from its {} frames: the camera did not move enough for a two-view "
                                 "geometry with key-image 0 (sigma_p threshold r_p {:.2f} px); {} not written",
                                 stats.frames, teacher.sigma_p_threshold_px(), args.map.string()));
  }
  double route_metres = 0.0;
  if (const auto truth_file = sequence->ground_truth_file();
      truth_file && truth_file->filename() == "poses.txt") {
    route_metres = RouteLengthMetres(map, ReadKittiPoses(*truth_file));
    database->SetMetadata(prefix + "route_length_m", fmt::format("{:.2f}", route_metres));
  }
  database->Checkpoint();
  // The ground's normal and the arcs' ground planes for repeat's metric path, fitted once here (the camera height is
  // the map's first teach's; arcs appended later are fitted by repeat).
  if (!existing && args.camera_height > 0) {
    TaughtPathOptions path_options;
    path_options.camera_height = args.camera_height;
    const auto fit_start = std::chrono::steady_clock::now();
    TravelModel travel;
    if (StoreGroundFits(database, *camera, path_options, &travel)) {
      std::cout << fmt::format("metric path: the ground's normal and every arc's ground plane stored ({:.1f} s)\n",
                               std::chrono::duration<double>(std::chrono::steady_clock::now() - fit_start).count());
      // The rig as the taught arcs show it (repeat/taught_path.h, TravelModel): a car's camera is 1-2 m ahead of
      // its rear axle; a robot that moves sideways fits no such model (repeat --travel-window 0).
      if (travel.valid && travel.turning_arcs > 0) {
        std::cout << fmt::format("vehicle: the camera travels as if {:.2f} m ahead of the point the robot turns "
                                 "about, yawed {:.2f} deg on its mount ({} turning and {} straight arcs)\n",
                                 travel.camera_ahead, travel.mount_yaw * 180 / M_PI, travel.turning_arcs,
                                 travel.straight_arcs);
      }
    } else {
      spdlog::warn("teach: no ground plane found between the key-images: repeat will have no metric path");
    }
    database->Checkpoint();
  }
  // The whole map's statistics (after --append: the map appended to with the new drive).
  const MapStatistics map_stats = ComputeMapStatistics(existing ? database->ReadMap(/*load_images=*/false) : map);
  staged->Commit();  // folds the write-ahead log into the map file and moves it into place
  const double map_kb = std::filesystem::file_size(args.map) / 1000.0;

  std::cout << fmt::format("map {}: {} key-images, {} arcs{} from {} frames\n", args.map.string(),
                           map_stats.num_nodes, map_stats.num_arcs, stats.loop_closed ? " (loop closed)" : "",
                           stats.frames);
  std::string reasons;
  for (int r = 0; r < static_cast<int>(stats.key_images_by_reason.size()); ++r) {
    if (stats.key_images_by_reason[r] == 0) continue;
    reasons += fmt::format("{}{} {}", reasons.empty() ? "" : ", ", stats.key_images_by_reason[r],
                           KeyImageReasonName(static_cast<KeyImageReason>(r)));
  }
  std::cout << "  key-images by reason: " << reasons << "\n";
  if (existing) {
    std::cout << fmt::format("  appended as route {} ({} key-images): {} join arcs to the map, {} key-images without "
                             "one\n",
                             map.nodes().empty() ? 0 : map.nodes().front().route, map.nodes().size(), stats.joins,
                             stats.key_images_without_join);
  }
  if (stats.gaps_recovered + stats.gaps_unrecovered > 0) {
    std::cout << fmt::format("  gaps: {} recovered by matching, {} not recovered\n", stats.gaps_recovered,
                             stats.gaps_unrecovered);
  }
  // More breaks than arcs: the pieces hold less than an arc each on average, a map repeat is lost on. Frames the
  // tracker cannot follow do that (kitti07 at 160x48 px: 62 breaks, 17 arcs); a drive with a few breaks is usable.
  if (stats.gaps_unrecovered > 0 && static_cast<size_t>(stats.gaps_unrecovered) > map_stats.num_arcs) {
    spdlog::warn("teach: the map is broken {} times and has {} arcs: repeat will be lost on most of it ({}x{} px "
                 "frames: too small or too blurred to track? a larger --width may help)",
                 stats.gaps_unrecovered, map_stats.num_arcs, camera->width(), camera->height());
  }
  // Join candidates (--append) are many where the drives overlap: counted, the first few described.
  constexpr int kJoinRejectionsShown = 3;
  int join_rejections = 0;
  for (const RejectedLink& link : stats.rejected_links) join_rejections += link.kind == "join";
  if (join_rejections > 0) {
    std::cout << fmt::format("  {} join candidates rejected{}\n", join_rejections,
                             join_rejections > kJoinRejectionsShown ? fmt::format(" (the first {}:)",
                                                                                   kJoinRejectionsShown)
                                                                     : ":");
  }
  int joins_shown = 0;
  for (const RejectedLink& link : stats.rejected_links) {
    if (link.kind == "join" && joins_shown++ >= kJoinRejectionsShown) continue;
    std::cout << fmt::format("  rejected {} link: key-image {} (frame {}) -> {} (frame {}), {} inliers, {} trackable, "
                             "sigma_p {:.2f} px: {}\n",
                             link.kind, link.from, link.from_frame, link.to, link.to_frame, link.inliers,
                             link.trackable, link.sigma_p, link.reason);
  }
  std::cout << fmt::format("  features per arc: median {:.0f}, min {:.0f}; sigma_p: median {:.2f}, max {:.2f} px "
                           "(r_p = {:.2f} px)\n",
                           map_stats.median_arc_features, map_stats.min_arc_features, map_stats.median_sigma_p,
                           map_stats.max_sigma_p, teacher.sigma_p_threshold_px());
  std::cout << fmt::format("  map size {:.1f} kB", map_kb);
  if (route_metres > 0) std::cout << fmt::format(" for {:.1f} m of route: {:.1f} kB/m", route_metres, map_kb / route_metres);
  std::cout << "\n";
  std::cout << fmt::format(
      "  time {:.2f} s ({:.1f} frames/s): reading {:.2f}, pyramid {:.2f}, tracking {:.2f}, geometry {:.2f}, "
      "detection {:.2f}, matching {:.2f}, storage {:.2f} s\n",
      seconds, stats.frames / std::max(seconds, 1e-9), seconds_reading, stats.seconds_pyramid, stats.seconds_tracking,
      stats.seconds_geometry, stats.seconds_detection, stats.seconds_matching, stats.seconds_storage);
}

}  // namespace

void RegisterTeachCommand(CLI::App& app) {
  auto args = std::make_shared<TeachArguments>();
  CLI::App* cmd = app.add_subcommand("teach", "Build a map (key-images linked by two-view geometries) from one drive");
  cmd->add_option("--sequence", args->sequence, "Image folder, video, KITTI or EuRoC layout, or ROS bag (*.bag)")
      ->required();
  AddBagOptions(cmd, &args->bag, /*with_camera_topic=*/true);
  cmd->add_option("--camera", args->camera, "Calibration file (default: the one found in the sequence)");
  cmd->add_option("--map", args->map, "Map file to write (SQLite)")->required();
  cmd->add_option("--method", args->method,
                  "tracking: key-images where the tracked geometry degrades (default); matching: every "
                  "--matching-interval frames, key-images inserted where arcs are weak (Segvic 2009 §5.1)")
      ->check(CLI::IsMember({"tracking", "matching"}))
      ->capture_default_str();
  cmd->add_option("--matching-interval", args->options.matching_interval,
                  "Frames between initial key-images of --method matching")
      ->capture_default_str();
  cmd->add_option("--width", args->width, "Work on images resized to this width (default: native)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--camera-height", args->camera_height,
                  "Height of the camera above the ground (m), stored in the map: repeat then measures the camera's "
                  "offset from the taught path in metres")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--every", args->every, "Use every k-th frame (e.g. 2 = even frames)")->check(CLI::PositiveNumber);
  cmd->add_option("--offset", args->offset, "First frame used with --every (1 = odd frames)");
  cmd->add_flag("--overwrite", args->overwrite,
                "Replace an existing map (only a retrace map, and only when teach succeeds: the map is written to "
                "MAP.incomplete and moved onto MAP at the end)");
  cmd->add_flag("--append", args->append,
                "Add the drive to the existing map MAP as its next route (same camera; at the map's key-image width "
                "unless --width is given) and link its key-images to the map where wide-baseline matching and a "
                "verified geometry show the same place (arcs of kind join); MAP is replaced only when teach succeeds");
  cmd->add_option("--min-join-similarity", args->options.min_join_similarity,
                  "--append: least appearance similarity S_ij of a join (Booij 2007: 0.05)")
      ->capture_default_str();
  cmd->add_option("--join-candidates", args->options.join_candidates,
                  "--append: existing key-images verified per key-image of the drive, closest in appearance first")
      ->capture_default_str();
  cmd->add_flag("--no-progress", args->no_progress, "Do not show the progress bar");
  cmd->add_option("--r-p", args->options.max_sigma_p_px, "r_p: sigma_p threshold for a new key-image, px at 320 px width")
      ->capture_default_str();
  cmd->add_option("--min-features", args->options.min_features, "n: fewest features an arc may keep")
      ->capture_default_str();
  cmd->add_option("--min-features-fraction", args->options.min_features_fraction,
                  "... or this fraction of the features tracked from the key-image, when more (0 = n alone)")
      ->capture_default_str();
  cmd->add_option("--max-residual", args->options.max_residual, "R: largest tracking residual, grey levels")
      ->capture_default_str();
  cmd->add_option("--max-corners", args->options.max_corners, "Corners tracked per subrange")->capture_default_str();
  cmd->add_option("--image-format", args->storage.image_format, "Key-image codec in the map: .jpg, .png or .webp")
      ->capture_default_str();
  cmd->add_option("--image-quality", args->storage.image_quality,
                  "Highest quality of lossy key-image codecs (1-100)")
      ->capture_default_str();
  cmd->add_option("--max-image-error", args->storage.max_image_error,
                  "Each key-image at the lowest quality whose error after the tracker's smoothing is at most this "
                  "(grey levels RMS; 0: always --image-quality)")
      ->capture_default_str();
  cmd->add_option("--max-image-downscale", args->storage.max_image_downscale,
                  "Key-images may be stored at 1/2 .. 1/N of their resolution when that keeps --max-image-error "
                  "and is smaller (1: always full resolution)")
      ->check(CLI::Range(1, 8))
      ->capture_default_str();
  cmd->add_flag("--no-loop-closing", [args](int64_t) { args->options.close_loop = false; },
                "Do not try to close the loop between the first and last key-image");
  cmd->add_flag("--no-gap-recovery", [args](int64_t) { args->options.recover_gaps = false; },
                "Do not relate frames across tracking failures by matching");
  cmd->add_flag("--verbatim-descriptors", args->verbatim_descriptors,
                "Store the key-images' relocalization descriptors as they are, not as their differences from the "
                "stored key-image's (a larger map; its descriptors are read without decoding key-images)");
  cmd->callback([args]() {
    std::string error;
    args->options.method =
        args->method == "matching" ? TeachOptions::Method::kMatching : TeachOptions::Method::kTracking;
    if (!args->options.Check(&error)) throw InputError("teach options", error);
    if (args->append && args->overwrite) throw InputError("teach options", "--append and --overwrite exclude each other");
    RunTeach(*args);
  });
}

}  // namespace retrace
