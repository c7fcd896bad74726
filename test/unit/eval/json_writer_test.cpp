#include "rankslam/eval/json_writer.hpp"

#include <gtest/gtest.h>

#include <limits>

namespace rankslam::eval {
namespace {

TEST(JsonWriter, WritesNestedObjectsNullsAndEscapes) {
  JsonWriter json;
  json.begin_object();
  json.integer("frames", 180).number("ate_rmse_m", 0.0123).null("rpe").string("name", "a\"b\\c\n");
  json.number("nan", std::numeric_limits<double>::quiet_NaN()).number("none", std::optional<double>{});
  json.begin_object("frame_ms").number("median", 9.5).end_object();
  json.boolean("ok", true).raw_object("config", "\"x\": 1");
  json.end_object();
  EXPECT_EQ(json.str(),
            "{\"frames\": 180, \"ate_rmse_m\": 0.0123, \"rpe\": null, \"name\": \"a\\\"b\\\\c\\n\", \"nan\": null, "
            "\"none\": null, \"frame_ms\": {\"median\": 9.5}, \"ok\": true, \"config\": {\"x\": 1}}\n");
}

}  // namespace
}  // namespace rankslam::eval
