// A picture of a solved scene for headless runs: each curve drawn as a band on each of its sides,
// coloured by that side's radiosity (tone-mapped), absorbing sides in dark grey. PNG via libpng.
#pragma once

#include <string>

#include "app/png_io.hpp"
#include "flatland/solver.hpp"

namespace flatland::app {

PngImage draw_picture(const Solver& solver, int width = 1024, int height = 768);

}  // namespace flatland::app
