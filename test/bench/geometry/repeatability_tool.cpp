// repeatability: relative repeatability of IS3D, ROS, uniform sampling and PCL's ISS keypoints
// on simulated pairs misaligned by 0, 5, 15 and 20° and on real TUM fr1 pairs (see
// repeatability.hpp for the construction). Prints a table.
//
//   repeatability [--scene NAME]... [--frames N] [--pairs N] [--no-real]
//                 [--ranking saliency|farthest|nearest] [--ros salient|first]
//                 [--set parameter=value]...

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>

#include "repeatability.hpp"

int main(int argc, char** argv) {
  rankslam::geometry::bench::RepeatabilityOptions options;
  bool scenes_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--scene" && i + 1 < argc) {
      if (!scenes_given) options.sim_scenes.clear();
      scenes_given = true;
      options.sim_scenes.emplace_back(argv[++i]);
    } else if (arg == "--frames" && i + 1 < argc) {
      options.sim_frames = std::atoi(argv[++i]);
    } else if (arg == "--pairs" && i + 1 < argc) {
      options.pairs_per_angle = std::atoi(argv[++i]);
    } else if (arg == "--no-real") {
      options.real_recordings.clear();
    } else if (arg == "--ranking" && i + 1 < argc) {
      options.config.is3d_ranking = std::strcmp(argv[++i], "nearest") == 0
                                        ? rankslam::geometry::Is3dRanking::kNearestToOrientations
                                        : std::strcmp(argv[i], "farthest") == 0
                                              ? rankslam::geometry::Is3dRanking::kFarthestFromOrientations
                                              : rankslam::geometry::Is3dRanking::kLocalSaliency;
    } else if (arg == "--ros" && i + 1 < argc) {
      options.config.ros_selection = std::strcmp(argv[++i], "first") == 0
                                         ? rankslam::geometry::RosSelection::kFirstPastTransition
                                         : rankslam::geometry::RosSelection::kMostSalient;
    } else if (arg == "--set" && i + 1 < argc) {
      const std::string kv = argv[++i];
      const auto eq = kv.find('=');
      bool found = false;
      if (eq != std::string::npos) {
        const std::string key = kv.substr(0, eq);
        const double value = std::atof(kv.c_str() + eq + 1);
        options.config.visit_parameters([&](std::string_view name, auto& field, auto, auto, auto, auto) {
          if (name == key) {
            field = static_cast<std::remove_reference_t<decltype(field)>>(value);
            found = true;
          }
        });
      }
      if (!found) {
        std::fprintf(stderr, "--set: unknown parameter in %s\n", kv.c_str());
        return 2;
      }
    } else {
      std::fprintf(stderr,
                   "usage: %s [--scene NAME]... [--frames N] [--pairs N] [--no-real] "
                   "[--ranking saliency|farthest|nearest] [--ros salient|first] "
                   "[--set parameter=value]...\n",
                   argv[0]);
      return 2;
    }
  }
  std::vector<rankslam::geometry::bench::RepeatabilityRow> rows;
  if (const std::string error = rankslam::geometry::bench::run_repeatability(options, rows); !error.empty()) {
    std::fprintf(stderr, "repeatability: %s\n", error.c_str());
    return 1;
  }
  std::fputs(rankslam::geometry::bench::format_repeatability_table(rows).c_str(), stdout);
  if (!rankslam::geometry::bench::have_iss()) std::puts("(ISS n/a: built without PCL)");
  return 0;
}
