// The text of a picture of `flatland render`: a title band above the stage (what the picture
// shows and how it was made) and the colour key with the materials' legend below it, as the
// viewer's key strip shows them. Drawn with Dear ImGui's OpenGL3 backend into whatever framebuffer
// is bound (the offscreen context's); desktop builds only.
#pragma once

#include <string>
#include <vector>

#include "flatland/base/status.hpp"
#include "viewer/frame.hpp"

namespace flatland::viewer {

struct PictureLayout {
  PixelRect title;     // empty without labels
  PixelRect stage;     // the scene is fitted into this
  PixelRect key;       // empty without labels
  float scale = 1.0f;  // the text's scale (ImGui's 13-pixel font times this)
};
// The picture's bands: with `labels`, three lines of title at the top and the key (its caption,
// scale, values, note and legend) at the bottom, the text scaled with the picture's height; a
// picture too small for them (under 320 x 240 pixels) keeps the whole picture for the stage.
PictureLayout picture_layout(int width, int height, bool labels);

// Draws `title_lines` in the layout's title band and the colour key of `snapshot` drawn with
// `options` in its key band. Nothing to do for a layout without labels.
Status draw_picture_labels(const Snapshot& snapshot, const DrawOptions& options, const PictureLayout& layout, int width,
                           int height, const std::vector<std::string>& title_lines);

}  // namespace flatland::viewer
