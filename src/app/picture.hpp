// A picture of a solved scene for headless runs: each curve drawn as a band on each of its sides,
// coloured by that side's radiosity (tone-mapped), absorbing sides in dark grey. PNG via libpng.
#pragma once

#include <string>

#include "flatland/transport/solver.hpp"
#include "png/png_io.hpp"

namespace flatland::app {

using png::encode_png;
using png::PngImage;

PngImage draw_picture(const Solver& solver, int width = 1024, int height = 768);

}  // namespace flatland::app
