#include "flatland/results/light_field.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace flatland {

Result<LightField> LightField::create(const Box& box, int resolution, int channels) {
  if (box.empty() || !is_finite(box.lower) || !is_finite(box.upper))
    return Error{"light field: the box must be finite and not empty"};
  if (resolution < 1 || resolution > 4096)
    return Error{"light field: resolution " + std::to_string(resolution) + " cells; use 1 to 4096"};
  if (channels != 1 && channels != 3) return Error{"light field: 1 or 3 channels"};
  const Vec2 extent = box.extent();
  const double longer = std::max(extent.x, extent.y);
  if (!(longer > 0.0) || !std::isfinite(longer)) return Error{"light field: the box has no extent"};
  LightField field;
  field.cell_ = longer / resolution;
  // At least one cell along the shorter side (a flat box still has a row of cells).
  field.width_ = std::clamp(static_cast<int>(std::ceil(extent.x / field.cell_ - 1e-9)), 1, resolution);
  field.height_ = std::clamp(static_cast<int>(std::ceil(extent.y / field.cell_ - 1e-9)), 1, resolution);
  field.box_.lower = box.lower;
  field.box_.upper = box.lower + Vec2{field.width_ * field.cell_, field.height_ * field.cell_};
  field.channels_ = channels;
  field.values_.assign(static_cast<std::size_t>(field.width_) * field.height_ * channels, 0.0);
  return field;
}

Result<LightField> LightField::for_scene(const Scene& scene, int resolution) {
  const Vec2 pad{0.05 * scene.scale, 0.05 * scene.scale};
  Box box;
  box.lower = scene.bounds.lower - pad;
  box.upper = scene.bounds.upper + pad;
  return create(box, resolution, scene.channels);
}

void LightField::add_leg(Vec2 a, Vec2 b, const Spectrum& power, double weight) {
  if (width_ == 0) return;
  const Vec2 d = b - a;
  const double len = length(d);
  if (!(len > 0.0) || !std::isfinite(len) || !(weight > 0.0)) return;
  // Clip to the box (Liang-Barsky): the leg is a + t d for t in [t0, t1].
  double t0 = 0.0;
  double t1 = 1.0;
  const double from[2] = {a.x, a.y};
  const double step[2] = {d.x, d.y};
  const double lower[2] = {box_.lower.x, box_.lower.y};
  const double upper[2] = {box_.upper.x, box_.upper.y};
  for (int axis = 0; axis < 2; ++axis) {
    if (step[axis] == 0.0) {
      if (from[axis] < lower[axis] || from[axis] > upper[axis]) return;
      continue;
    }
    double ta = (lower[axis] - from[axis]) / step[axis];
    double tb = (upper[axis] - from[axis]) / step[axis];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (!(t0 < t1)) return;

  // Walk the cells the leg crosses (Amanatides and Woo): the next grid line of each axis is
  // met at t_next[axis], one cell further every t_step[axis]; between consecutive crossings the
  // leg lies in one cell and books (end - t) of its length there. The lengths telescope, so the
  // leg's whole clipped length is booked whatever the crossings' rounding; an index that rounding
  // pushes past the grid's edge is clamped.
  const double scale = weight * len / (cell_ * cell_);
  Spectrum add{};
  for (int ch = 0; ch < channels_; ++ch)
    add[static_cast<std::size_t>(ch)] = power[static_cast<std::size_t>(ch)] * scale;
  const int cells[2] = {width_, height_};
  int index[2];
  int direction[2] = {0, 0};
  double t_next[2] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  double t_step[2] = {0.0, 0.0};
  for (int axis = 0; axis < 2; ++axis) {
    const double g = (from[axis] + t0 * step[axis] - lower[axis]) / cell_;
    if (step[axis] > 0.0) {
      direction[axis] = 1;
      index[axis] = static_cast<int>(std::floor(g));
    } else if (step[axis] < 0.0) {
      direction[axis] = -1;
      index[axis] = static_cast<int>(std::ceil(g)) - 1;
    } else {
      index[axis] = static_cast<int>(std::floor(g));
    }
    index[axis] = std::clamp(index[axis], 0, cells[axis] - 1);
    if (direction[axis] != 0) {
      const int line = direction[axis] > 0 ? index[axis] + 1 : index[axis];
      t_next[axis] = (lower[axis] + line * cell_ - from[axis]) / step[axis];
      t_step[axis] = cell_ / std::fabs(step[axis]);
    }
  }
  double t = t0;
  const auto row_length = static_cast<std::size_t>(width_);
  const auto channels = static_cast<std::size_t>(channels_);
  for (;;) {
    const int axis = t_next[0] < t_next[1] ? 0 : 1;
    const double end = std::min(t_next[axis], t1);
    if (end > t) {
      double* cell = values_.data() +
                     (static_cast<std::size_t>(index[1]) * row_length + static_cast<std::size_t>(index[0])) * channels;
      const double piece = end - t;
      for (std::size_t ch = 0; ch < channels; ++ch) cell[ch] += add[ch] * piece;
      t = end;
    }
    if (end >= t1) break;
    const int next = index[axis] + direction[axis];
    if (next < 0 || next >= cells[axis]) {
      // Round-off put the last crossing before t1 at the grid's edge: the rest is in this cell.
      if (t1 > t) {
        double* cell =
            values_.data() +
            (static_cast<std::size_t>(index[1]) * row_length + static_cast<std::size_t>(index[0])) * channels;
        for (std::size_t ch = 0; ch < channels; ++ch) cell[ch] += add[ch] * (t1 - t);
      }
      break;
    }
    index[axis] = next;
    t_next[axis] += t_step[axis];
  }
}

void LightField::add_flight(const PhotonPath& path, double weight) {
  Vec2 from = path.origin;
  for (const Vec2& point : path.via) {
    add_leg(from, point, path.power, weight);
    from = point;
  }
  if (!path.escaped) {
    add_leg(from, path.end, path.power, weight);
    return;
  }
  // Escaped: `end` is the last point plus the flight's direction; go on past the grid's box.
  const Vec2 d = path.end - from;
  const double d_len = length(d);
  if (!(d_len > 0.0)) return;
  const double reach = length(from - box_.center()) + box_.diagonal();
  add_leg(from, from + d * (reach / d_len), path.power, weight);
}

namespace {

// A walk that goes on past the first n flights of `record` (n >= 1): its last kept hop was cut by
// the solver, or the flight after it continues the walk.
bool cut_at(const std::vector<PhotonPath>& record, std::size_t n) {
  return record[n - 1].cut || (n < record.size() && record[n].bounce != 0);
}

// The flights among the first `count` of `record` that make whole photons, [0, whole), and how
// many photons they are. Shooting: every flight is a photon. Walks: a flight with bounce 0 starts
// one; the last walk is whole unless it was cut.
std::pair<std::size_t, std::size_t> whole_photons(const std::vector<PhotonPath>& record, std::size_t count,
                                                  Transport transport) {
  const std::size_t n = std::min(count, record.size());
  if (n == 0 || transport != Transport::Walk) return {n, n};
  std::size_t photons = 0;
  std::size_t last_start = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (record[i].bounce == 0) {
      ++photons;
      last_start = i;
    }
  if (cut_at(record, n) && photons > 0) return {last_start, photons - 1};
  return {n, photons};
}

}  // namespace

void truncate_record(std::vector<PhotonPath>& record, std::size_t n, Transport transport) {
  if (record.size() <= n) return;
  if (n > 0 && transport == Transport::Walk && cut_at(record, n)) record[n - 1].cut = true;
  record.resize(n);
}

std::size_t LightField::add_flights(const std::vector<PhotonPath>& flights, std::size_t count, Transport transport) {
  const auto [whole, photons] = whole_photons(flights, count, transport);
  for (std::size_t i = 0; i < whole; ++i) add_flight(flights[i], 1.0);
  return photons;
}

void LightField::add(const LightField& other, double weight, double photons) {
  if (other.values_.size() != values_.size()) return;
  for (std::size_t i = 0; i < values_.size(); ++i) values_[i] += weight * other.values_[i];
  photons_ += photons;
}

std::size_t LightField::add_record(const std::vector<PhotonPath>& record, std::uint64_t shot, Transport transport) {
  if (record.empty() || shot == 0) return 0;
  auto [whole, photons] = whole_photons(record, record.size(), transport);
  photons = std::min<std::size_t>(photons, shot);
  if (photons == 0) return 0;
  const double weight = static_cast<double>(shot) / static_cast<double>(photons);
  for (std::size_t i = 0; i < whole; ++i) add_flight(record[i], weight);
  photons_ += static_cast<double>(shot);
  return photons;
}

double LightField::quantile(double q) const {
  std::vector<double> lit;
  lit.reserve(values_.size() / static_cast<std::size_t>(std::max(channels_, 1)));
  for (std::size_t i = 0; i < values_.size(); i += static_cast<std::size_t>(channels_)) {
    double sum = 0.0;
    for (int ch = 0; ch < channels_; ++ch) sum += values_[i + static_cast<std::size_t>(ch)];
    if (sum > 0.0) lit.push_back(sum / channels_);
  }
  if (lit.empty()) return 0.0;
  const double clamped = std::clamp(q, 0.0, 1.0);
  const auto k = static_cast<std::size_t>(std::clamp(std::ceil(clamped * static_cast<double>(lit.size())) - 1.0, 0.0,
                                                     static_cast<double>(lit.size()) - 1.0));
  std::nth_element(lit.begin(), lit.begin() + static_cast<std::ptrdiff_t>(k), lit.end());
  return lit[k];
}

void LightField::clear() {
  std::fill(values_.begin(), values_.end(), 0.0);
  photons_ = 0.0;
}

}  // namespace flatland
