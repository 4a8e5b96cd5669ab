// Contact sheets: the grid's size from the frames' size, the frames drawn into it, and
// errors for frames that cannot be read.
#include "skinserve/render/contact_sheet.h"

#include <gtest/gtest.h>

#include <cairo.h>

#include <cmath>

#include "png_pixels.h"

namespace skinserve::testing {
namespace {

// A frame filled with one colour.
std::string SolidPng(const std::string& name, int width, int height, double r, double g, double b) {
  const std::string path = ::testing::TempDir() + name;
  cairo_surface_t* s = cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height);
  cairo_t* cr = cairo_create(s);
  cairo_set_source_rgb(cr, r, g, b);
  cairo_paint(cr);
  EXPECT_EQ(cairo_status(cr), CAIRO_STATUS_SUCCESS);
  EXPECT_EQ(cairo_surface_write_to_png(s, path.c_str()), CAIRO_STATUS_SUCCESS);
  cairo_destroy(cr);
  cairo_surface_destroy(s);
  return path;
}

TEST(ContactSheetTest, GridOfScaledFramesWithLabels) {
  std::vector<render::SheetFrame> frames;
  for (int i = 0; i < 5; ++i) {
    frames.push_back({SolidPng("sheet-" + std::to_string(i) + ".png", 400, 200, 0.0, 0.2 * i, 1.0),
                      "frame " + std::to_string(i)});
  }
  const render::SheetOptions options{.columns = 4, .width = 800, .label_height = 20};
  const render::SheetSize size = render::ContactSheetSize(5, 400, 200, options);
  EXPECT_EQ(size.width, 800);
  EXPECT_EQ(size.height, 2 * (100 + 20));  // 2 rows of 200 x 100 cells plus labels

  const std::string path = ::testing::TempDir() + "sheet.png";
  const Status s = render::WriteContactSheet(path, frames, options);
  ASSERT_TRUE(s.ok()) << s.ToString();
  const Pixels sheet = ReadPng(path);
  ASSERT_EQ(sheet.width, 800);
  ASSERT_EQ(sheet.height, 240);
  // The centre of each cell shows its frame's colour; the sixth cell is empty (white).
  for (int i = 0; i < 5; ++i) {
    const int x = (i % 4) * 200 + 100, y = (i / 4) * 120 + 50;
    const uint32_t green = static_cast<uint32_t>(std::lround(0.2 * i * 255));
    EXPECT_EQ(sheet.at(x, y), green << 8 | 0xFFu) << "cell " << i;
  }
  EXPECT_EQ(sheet.at(300, 170), 0xFFFFFFu);
}

TEST(ContactSheetTest, UnreadableFramesAndBadOptionsAreErrors) {
  const std::vector<render::SheetFrame> missing = {{"/nonexistent-dir/frame_0000.png", ""}};
  Status s = render::WriteContactSheet(::testing::TempDir() + "sheet-bad.png", missing);
  EXPECT_EQ(s.code(), StatusCode::kInternal);
  EXPECT_NE(s.message().find("/nonexistent-dir/frame_0000.png"), std::string::npos);
  EXPECT_EQ(render::WriteContactSheet(::testing::TempDir() + "sheet-bad.png", {}).code(),
            StatusCode::kInvalidArgument);
  const std::vector<render::SheetFrame> one = {{SolidPng("one.png", 10, 10, 1, 0, 0), ""}};
  EXPECT_EQ(
      render::WriteContactSheet(::testing::TempDir() + "sheet-bad.png", one, {.columns = 0}).code(),
      StatusCode::kInvalidArgument);
}

TEST(ContactSheetTest, EvenlySpacedPicksSpreadOverTheFrames) {
  EXPECT_EQ(render::EvenlySpaced(3, 8), (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_EQ(render::EvenlySpaced(60, 4), (std::vector<std::size_t>{0, 15, 30, 45}));
}

}  // namespace
}  // namespace skinserve::testing
