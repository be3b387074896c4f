#include "npfkct/sim/scenegen.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/sim/oracle.h"
#include "npfkct/sim/scenario.h"
#include "npfkct/sim/simulator.h"

namespace npfkct::sim {
namespace {

using nlohmann::json;
using object_search::Vec2;

constexpr double kPi = std::numbers::pi;

// Millimetre precision keeps the files short and readable.
double R3(double v) { return std::round(v * 1000.0) / 1000.0; }

struct GenFurniture {
  std::string name;
  Vec2 center = Vec2::Zero();
  double length = 1.0, width = 0.6, height = 0.75, yaw = 0.0;
  Color color{};
  Vec2 Local(const Vec2& uv) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return center + Vec2(c * uv.x() - s * uv.y(), s * uv.x() + c * uv.y());
  }
  double Radius() const { return 0.5 * std::hypot(length, width); }
};

struct GenObject {
  std::string name;
  int on = 0;
  Vec2 uv = Vec2::Zero();  // position in the workspace frame
  double z = 0.0;          // height above the surface
  object_search::Vec3 size = object_search::Vec3::Constant(0.1);
  double yaw = 0.0;  // relative to the workspace
  Color color{};
  bool target = false;
  bool moveable = true;
  uint32_t texture = 0;
  // Half-diagonal of the footprint, for non-overlap tests.
  double Radius() const { return 0.5 * std::hypot(size.x(), size.y()); }
};

Color RandomColor(Rng& rng) {
  return {static_cast<uint8_t>(30 + rng.UniformInt(200)),
          static_cast<uint8_t>(30 + rng.UniformInt(200)),
          static_cast<uint8_t>(30 + rng.UniformInt(200))};
}

// Whether the footprint of `o` (rotated by its yaw) lies on the surface of `f`.
bool OnSurface(const GenFurniture& f, const GenObject& o, double margin = 0.01) {
  const double c = std::cos(o.yaw), s = std::sin(o.yaw);
  for (int k = 0; k < 4; ++k) {
    const double du = (k & 1 ? 0.5 : -0.5) * o.size.x(), dv = (k & 2 ? 0.5 : -0.5) * o.size.y();
    const double u = o.uv.x() + c * du - s * dv, v = o.uv.y() + s * du + c * dv;
    if (std::abs(u) > 0.5 * f.length - margin || std::abs(v) > 0.5 * f.width - margin) return false;
  }
  return true;
}

bool Overlaps(const GenObject& a, const std::vector<GenObject>& others, double gap = 0.02) {
  for (const GenObject& b : others) {
    if (b.on != a.on) continue;
    if ((a.uv - b.uv).norm() < a.Radius() + b.Radius() + gap) return true;
  }
  return false;
}

json Pair(double a, double b) { return json::array({R3(a), R3(b)}); }

class Generator {
 public:
  // A scene named after `seed`, drawn from `draw` (the seed itself, or a redraw of it).
  Generator(uint64_t seed, uint64_t draw, const SceneOptions& options)
      : seed_(seed), rng_(draw * 0x9e3779b97f4a7c15ULL + 0x5eed), options_(options) {}

  json Make(SceneSummary* summary) {
    robot_ = rng_.Bernoulli(0.5) ? "fetch" : "stretch";
    room_ = Vec2(rng_.Uniform(5.0, 8.0), rng_.Uniform(5.0, 8.0));
    PlaceFurniture(1 + static_cast<int>(rng_.UniformInt(4)));
    const double r = rng_.Uniform();
    placement_ = r < 0.4 ? TargetPlacement::kOpen
                         : (r < 0.7 ? TargetPlacement::kHidden : TargetPlacement::kCovered);
    if (options_.version >= 2) {
      placement_ = static_cast<TargetPlacement>(std::min(2, static_cast<int>(3 * r)));
    }
    if (options_.placement) placement_ = *options_.placement;
    if (options_.version >= 2) {
      PlaceTargetV2();
      PlaceDecoys();
      PlaceOthers(static_cast<int>(objects_.size()) + 3 + static_cast<int>(rng_.UniformInt(30)));
    } else {
      PlaceTarget();
      PlaceOthers(3 + static_cast<int>(rng_.UniformInt(38)));
    }
    json j = ToJson();
    if (summary != nullptr) {
      summary->robot = robot_;
      summary->furniture = static_cast<int>(furniture_.size());
      summary->objects = static_cast<int>(objects_.size());
      summary->placement = placement_;
      summary->variant = variant_;
      summary->decoys = decoys_;
    }
    return j;
  }

 private:
  void PlaceFurniture(int count) {
    const Vec2 half = 0.5 * room_;
    for (int i = 0; i < count; ++i) {
      for (int attempt = 0; attempt < 200; ++attempt) {
        GenFurniture f;
        f.name = "furniture-" + std::to_string(i + 1);
        f.length = rng_.Uniform(0.6, 1.6);
        f.width = rng_.Uniform(0.4, 0.9);
        f.height = rng_.Uniform(0.4, 1.1);
        // Half of the pieces stand square to the room, the others at any angle.
        f.yaw = rng_.Bernoulli(0.5) ? 0.5 * kPi * static_cast<double>(rng_.UniformInt(4))
                                    : rng_.Uniform(-kPi, kPi);
        f.yaw = object_search::WrapAngle(f.yaw);
        f.color = RandomColor(rng_);
        // Room for base regions (0.35-0.85 m from the sides) between pieces and walls.
        const double margin = f.Radius() + 1.0;
        if (half.x() <= margin || half.y() <= margin) continue;
        f.center = Vec2(rng_.Uniform(-half.x() + margin, half.x() - margin),
                        rng_.Uniform(-half.y() + margin, half.y() - margin));
        const bool clear = std::all_of(furniture_.begin(), furniture_.end(), [&](const auto& g) {
          return (g.center - f.center).norm() > g.Radius() + f.Radius() + 1.7;
        });
        if (!clear) continue;
        furniture_.push_back(f);
        break;
      }
    }
    if (furniture_.empty()) {  // a small room that fits nothing else: one table in the middle
      GenFurniture f;
      f.name = "furniture-1";
      f.length = 1.0;
      f.width = 0.6;
      f.height = 0.75;
      f.color = RandomColor(rng_);
      furniture_.push_back(f);
    }
  }

  GenObject RandomObject(int on, Rng& rng) {
    GenObject o;
    o.on = on;
    o.size =
        object_search::Vec3(rng.Uniform(0.05, 0.2), rng.Uniform(0.05, 0.2), rng.Uniform(0.05, 0.3));
    o.yaw = rng.Uniform(-0.5 * kPi, 0.5 * kPi);
    o.color = RandomColor(rng);
    o.moveable = rng.Bernoulli(0.9);
    const GenFurniture& f = furniture_[on];
    o.uv = Vec2(rng.Uniform(-0.5, 0.5) * f.length, rng.Uniform(-0.5, 0.5) * f.width);
    return o;
  }

  // The target's furniture, size, colour and texture; its yaw (0 unless `any_yaw`); its place
  // within `reach` times the furniture's length and width of the top's centre.
  GenObject DrawTarget(bool any_yaw, double reach) {
    GenObject t;
    t.name = "target";
    t.target = true;
    t.on = static_cast<int>(rng_.UniformInt(static_cast<int64_t>(furniture_.size())));
    const GenFurniture& f = furniture_[t.on];
    t.size = object_search::Vec3(rng_.Uniform(0.06, 0.14), rng_.Uniform(0.06, 0.14),
                                 rng_.Uniform(0.08, 0.18));
    t.color = RandomColor(rng_);
    t.texture = 1 + static_cast<uint32_t>(rng_.UniformInt(2000000000));
    t.yaw = any_yaw ? rng_.Uniform(-0.5 * kPi, 0.5 * kPi) : 0.0;
    t.uv = Vec2(rng_.Uniform(-reach, reach) * f.length, rng_.Uniform(-reach, reach) * f.width);
    return t;
  }

  // Adds the target and what hides it when all of them stand on furniture f, or after 100
  // attempts (then as a target in the open, never reached in practice); whether it added them.
  bool Commit(const GenFurniture& f, const GenObject& t, const std::vector<GenObject>& extra,
              int attempt) {
    bool fits = OnSurface(f, t);
    for (const GenObject& e : extra) fits = fits && OnSurface(f, e);
    if (!fits && attempt <= 100) return false;
    objects_.push_back(t);
    for (const GenObject& e : extra) objects_.push_back(e);
    if (!fits) placement_ = TargetPlacement::kOpen;
    return true;
  }

  void PlaceTarget() {
    for (int attempt = 0;; ++attempt) {
      GenObject t = DrawTarget(placement_ == TargetPlacement::kOpen, 0.35);
      const GenFurniture& f = furniture_[t.on];
      std::vector<GenObject> extra;
      if (placement_ == TargetPlacement::kCovered) {
        GenObject cover;
        cover.name = "cover";
        cover.on = t.on;
        cover.uv = t.uv;
        cover.size =
            t.size + object_search::Vec3(rng_.Uniform(0.06, 0.14), rng_.Uniform(0.06, 0.14),
                                         rng_.Uniform(0.05, 0.12));
        cover.color = RandomColor(rng_);
        extra.push_back(cover);
      } else if (placement_ == TargetPlacement::kHidden) {
        // Tall boxes on one to three of the four sides; the last side stays open.
        std::array<int, 4> sides = {0, 1, 2, 3};
        for (int k = 3; k > 0; --k) std::swap(sides[k], sides[rng_.UniformInt(k + 1)]);
        const int walls = 1 + static_cast<int>(rng_.UniformInt(3));
        for (int w = 0; w < walls; ++w) {
          const int side = sides[w];
          const bool along_u = side < 2;
          const double dir = side % 2 ? 1.0 : -1.0;
          GenObject wall;
          wall.name = "wall-" + std::to_string(w + 1);
          wall.on = t.on;
          const double depth = rng_.Uniform(0.05, 0.08);
          const double span = (along_u ? t.size.y() : t.size.x()) + rng_.Uniform(0.08, 0.2);
          wall.size =
              along_u ? object_search::Vec3(depth, span, 0) : object_search::Vec3(span, depth, 0);
          wall.size.z() = t.size.z() + rng_.Uniform(0.08, 0.2);
          const double offset = 0.5 * (along_u ? t.size.x() : t.size.y()) + 0.5 * depth + 0.015;
          wall.uv = t.uv + (along_u ? Vec2(dir * offset, 0) : Vec2(0, dir * offset));
          wall.color = RandomColor(rng_);
          extra.push_back(wall);
        }
      }
      if (Commit(f, t, extra, attempt)) return;
    }
  }

  // ---- version 2 ----

  // A cover's size law: the box it covers, larger by 0.06-0.14 m across and 0.05-0.12 m up.
  object_search::Vec3 CoverSize(const object_search::Vec3& inner) {
    return inner + object_search::Vec3(rng_.Uniform(0.06, 0.14), rng_.Uniform(0.06, 0.14),
                                       rng_.Uniform(0.05, 0.12));
  }

  // Tall boxes (walls) on `count` of the four sides of a footprint of `size` at `uv` with `yaw`,
  // in its frame; the remaining sides stay open.
  std::vector<GenObject> Walls(int on, const Vec2& uv, double yaw, const object_search::Vec3& size,
                               int count, const std::string& prefix) {
    std::array<int, 4> sides = {0, 1, 2, 3};
    for (int k = 3; k > 0; --k) std::swap(sides[k], sides[rng_.UniformInt(k + 1)]);
    std::vector<GenObject> walls;
    const double c = std::cos(yaw), s = std::sin(yaw);
    for (int w = 0; w < count; ++w) {
      const int side = sides[w];
      const bool along_u = side < 2;
      const double dir = side % 2 ? 1.0 : -1.0;
      GenObject wall;
      wall.name = prefix + std::to_string(w + 1);
      wall.on = on;
      const double depth = rng_.Uniform(0.05, 0.08);
      const double span = (along_u ? size.y() : size.x()) + rng_.Uniform(0.08, 0.2);
      wall.size =
          along_u ? object_search::Vec3(depth, span, 0) : object_search::Vec3(span, depth, 0);
      wall.size.z() = size.z() + rng_.Uniform(0.08, 0.2);
      const double offset = 0.5 * (along_u ? size.x() : size.y()) + 0.5 * depth + 0.015;
      const Vec2 local = along_u ? Vec2(dir * offset, 0) : Vec2(0, dir * offset);
      wall.uv = uv + Vec2(c * local.x() - s * local.y(), s * local.x() + c * local.y());
      wall.yaw = yaw;
      wall.color = RandomColor(rng_);
      walls.push_back(wall);
    }
    return walls;
  }

  // The target at any yaw, and what hides it: walls on one to three sides (or three, deeper:
  // a pocket), or a cover (alone, under a second cover, or walled on one to two sides); a few
  // small boxes beside it.
  void PlaceTargetV2() {
    for (int attempt = 0;; ++attempt) {
      GenObject t = DrawTarget(true, 0.3);
      const GenFurniture& f = furniture_[t.on];
      std::vector<GenObject> extra;
      const double kind = rng_.Uniform();
      variant_ = "open";
      if (placement_ == TargetPlacement::kHidden) {
        const bool pocket = kind < 0.3;
        variant_ = pocket ? "pocket" : "walls";
        extra = Walls(t.on, t.uv, t.yaw, t.size,
                      pocket ? 3 : 1 + static_cast<int>(rng_.UniformInt(3)), "wall-");
        if (pocket) {
          for (GenObject& w : extra) w.size.z() += 0.1;
        }
      } else if (placement_ == TargetPlacement::kCovered) {
        GenObject cover;
        cover.name = "cover";
        cover.on = t.on;
        cover.uv = t.uv;
        cover.yaw = t.yaw;
        cover.size = CoverSize(t.size);
        cover.color = RandomColor(rng_);
        extra.push_back(cover);
        variant_ = "cover";
        if (kind < 0.25) {
          GenObject outer = cover;
          outer.name = "outer-cover";
          outer.size = CoverSize(cover.size);
          outer.color = RandomColor(rng_);
          extra.push_back(outer);
          variant_ = "stacked covers";
        } else if (kind < 0.5) {
          for (GenObject& w : Walls(t.on, t.uv, t.yaw, cover.size,
                                    1 + static_cast<int>(rng_.UniformInt(2)), "wall-")) {
            extra.push_back(w);
          }
          variant_ = "walled cover";
        }
      }
      // Small boxes beside it, clear of what hides it.
      const int clutter = 1 + static_cast<int>(rng_.UniformInt(4));
      std::vector<GenObject> placed = extra;
      placed.push_back(t);
      for (int k = 0, tries = 0; k < clutter && tries < 60; ++tries) {
        GenObject o = RandomObject(t.on, rng_);
        o.size = object_search::Vec3(rng_.Uniform(0.04, 0.1), rng_.Uniform(0.04, 0.1),
                                     rng_.Uniform(0.04, 0.15));
        const double angle = rng_.Uniform(-kPi, kPi), distance = rng_.Uniform(0.15, 0.35);
        o.uv = t.uv + distance * Vec2(std::cos(angle), std::sin(angle));
        if (!OnSurface(f, o) || Overlaps(o, placed)) continue;
        o.name = "near-" + std::to_string(++k);
        placed.push_back(o);
        extra.push_back(o);
      }
      if (Commit(f, t, extra, attempt)) return;
    }
  }

  // Decoys from the same laws, elsewhere and empty: covers (so the cover is not the largest box
  // nor the only one of its kind), wall pockets, and immovable boxes larger than any cover.
  void PlaceDecoys() {
    const int covers = 1 + static_cast<int>(rng_.UniformInt(3));
    const int pockets = static_cast<int>(rng_.UniformInt(3));
    const int heavy = static_cast<int>(rng_.UniformInt(3));
    for (int k = 0, tries = 0; k < covers + pockets + heavy && tries < 400; ++tries) {
      const int on = static_cast<int>(rng_.UniformInt(static_cast<int64_t>(furniture_.size())));
      GenObject o = RandomObject(on, rng_);
      const object_search::Vec3 inner(rng_.Uniform(0.06, 0.14), rng_.Uniform(0.06, 0.14),
                                      rng_.Uniform(0.08, 0.18));
      std::vector<GenObject> group;
      if (k < covers) {
        o.size = CoverSize(inner);
        o.moveable = true;
        o.name = "decoy-cover-" + std::to_string(k + 1);
        group.push_back(o);
      } else if (k < covers + pockets) {
        group = Walls(on, o.uv, o.yaw, inner, 2 + static_cast<int>(rng_.UniformInt(2)),
                      "decoy-wall-" + std::to_string(k + 1) + "-");
      } else {
        o.size = object_search::Vec3(rng_.Uniform(0.2, 0.32), rng_.Uniform(0.2, 0.32),
                                     rng_.Uniform(0.15, 0.35));
        o.moveable = false;
        o.name = "heavy-" + std::to_string(k + 1);
        group.push_back(o);
      }
      bool fits = true;
      for (const GenObject& g : group) {
        fits = fits && OnSurface(furniture_[on], g) && !Overlaps(g, objects_, 0.04);
      }
      if (!fits) continue;
      for (GenObject& g : group) objects_.push_back(g);
      ++k;
      ++decoys_;
    }
  }

  void PlaceOthers(int total) {
    Rng rng = rng_.Split();
    int placed = static_cast<int>(objects_.size());
    for (int attempt = 0; placed < total && attempt < 40 * total; ++attempt) {
      const int on = static_cast<int>(rng.UniformInt(static_cast<int64_t>(furniture_.size())));
      GenObject o = RandomObject(on, rng);
      if (!OnSurface(furniture_[on], o) || Overlaps(o, objects_)) continue;
      o.name = "box-" + std::to_string(placed);
      objects_.push_back(o);
      ++placed;
    }
  }

  json ToJson() {
    json j;
    j["name"] = "gen-" + std::to_string(seed_);
    static const char* kPlacements[] = {"in the open", "hidden behind tall boxes",
                                        "covered by a larger box"};
    j["description"] =
        "Generated by npfkct-scenegen --seed " + std::to_string(seed_) +
        (options_.version >= 2 ? " --version 2" : "") + ": " + std::to_string(furniture_.size()) +
        (furniture_.size() == 1 ? " piece" : " pieces") + " of furniture, " +
        std::to_string(objects_.size()) + " objects, the target " +
        kPlacements[static_cast<int>(placement_)] +
        (options_.version >= 2 ? " (" + variant_ + ", " + std::to_string(decoys_) + " decoys)"
                               : std::string()) +
        ".";
    j["robot"] = robot_;
    j["room"] = {{"min", Pair(-0.5 * room_.x(), -0.5 * room_.y())},
                 {"max", Pair(0.5 * room_.x(), 0.5 * room_.y())}};
    j["mapResolution"] = 0.05;
    json furniture = json::array();
    for (const GenFurniture& f : furniture_) {
      furniture.push_back({{"name", f.name},
                           {"center", Pair(f.center.x(), f.center.y())},
                           {"size", json::array({R3(f.length), R3(f.width), R3(f.height)})},
                           {"yaw", R3(f.yaw)},
                           {"workspace", true},
                           {"color", json::array({f.color[0], f.color[1], f.color[2]})}});
    }
    j["furniture"] = furniture;
    j["baseRegions"] = BaseRegions();
    json objects = json::array();
    for (const GenObject& o : objects_) {
      json jo = {{"name", o.name},
                 {"on", furniture_[o.on].name},
                 {"position", Pair(o.uv.x(), o.uv.y())},
                 {"size", json::array({R3(o.size.x()), R3(o.size.y()), R3(o.size.z())})},
                 {"yaw", R3(o.yaw)},
                 {"color", json::array({o.color[0], o.color[1], o.color[2]})}};
      if (o.z > 0) jo["z"] = R3(o.z);
      if (o.target) jo["target"] = true;
      if (!o.moveable) jo["moveable"] = false;
      if (o.texture != 0) jo["texture"] = o.texture;
      objects.push_back(jo);
    }
    j["objects"] = objects;
    j["start"] = Start();
    return j;
  }

  // Axis-aligned squares beside every side of every piece (two along sides over 1 m), kept when
  // enough of them is free for the base.
  json BaseRegions() {
    json regions = json::array();
    const Vec2 half = 0.5 * room_;
    const double footprint = robot_ == "fetch" ? 0.3 : 0.2;
    for (const GenFurniture& f : furniture_) {
      for (int side = 0; side < 4; ++side) {
        const bool along_u = side < 2;
        const double dir = side % 2 ? 1.0 : -1.0;
        const double extent = along_u ? 0.5 * f.length : 0.5 * f.width;
        const double span = along_u ? f.width : f.length;
        const std::vector<double> offsets =
            span > 1.0 ? std::vector<double>{-0.25 * span, 0.25 * span} : std::vector<double>{0.0};
        for (double t : offsets) {
          const Vec2 local =
              along_u ? Vec2(dir * (extent + 0.6), t) : Vec2(t, dir * (extent + 0.6));
          const Vec2 c = f.Local(local);
          const Vec2 lo = c - Vec2(0.25, 0.25), hi = c + Vec2(0.25, 0.25);
          if (lo.x() < -half.x() + footprint || lo.y() < -half.y() + footprint ||
              hi.x() > half.x() - footprint || hi.y() > half.y() - footprint) {
            continue;
          }
          if (FreeShare(lo, hi, footprint) < 0.25) continue;
          regions.push_back({{"min", Pair(lo.x(), lo.y())}, {"max", Pair(hi.x(), hi.y())}});
        }
      }
    }
    return regions;
  }

  // The share of a 6 x 6 grid over [lo, hi] where a base of radius r stands free of every piece.
  double FreeShare(const Vec2& lo, const Vec2& hi, double r) const {
    int free = 0;
    for (int a = 0; a < 6; ++a) {
      for (int b = 0; b < 6; ++b) {
        const Vec2 p(lo.x() + (hi.x() - lo.x()) * (a + 0.5) / 6.0,
                     lo.y() + (hi.y() - lo.y()) * (b + 0.5) / 6.0);
        free += std::all_of(furniture_.begin(), furniture_.end(),
                            [&](const GenFurniture& f) { return DistanceTo(f, p) > r + 0.05; });
      }
    }
    return free / 36.0;
  }

  // Distance from p to the footprint rectangle of f.
  static double DistanceTo(const GenFurniture& f, const Vec2& p) {
    const double c = std::cos(f.yaw), s = std::sin(f.yaw);
    const Vec2 d = p - f.center;
    const double u = std::abs(c * d.x() + s * d.y()) - 0.5 * f.length;
    const double v = std::abs(-s * d.x() + c * d.y()) - 0.5 * f.width;
    return std::hypot(std::max(u, 0.0), std::max(v, 0.0)) + std::min(std::max(u, v), 0.0);
  }

  // The rest pose (lift 0, head level) at a free spot from which no workspace is within the
  // camera's range, so that the first view is planned; else the free spot farthest from them.
  json Start() {
    const Vec2 half = 0.5 * room_;
    const double footprint = robot_ == "fetch" ? 0.3 : 0.2;
    std::vector<Vec2> far, all;
    double best_d = -1.0;
    Vec2 best = Vec2::Zero();
    for (double x = -half.x() + 0.5; x <= half.x() - 0.5; x += 0.25) {
      for (double y = -half.y() + 0.5; y <= half.y() - 0.5; y += 0.25) {
        const Vec2 p(x, y);
        double d = 1e9;
        for (const GenFurniture& f : furniture_) d = std::min(d, DistanceTo(f, p));
        if (d < footprint + 0.15) continue;
        if (d > 2.0) far.push_back(p);
        if (d > best_d) {
          best_d = d;
          best = p;
        }
      }
    }
    const Vec2 p = far.empty() ? best : far[rng_.UniformInt(static_cast<int64_t>(far.size()))];
    return {{"x", R3(p.x())}, {"y", R3(p.y())}, {"yaw", R3(rng_.Uniform(-kPi, kPi))},
            {"lift", 0.0},    {"pan", 0.0},     {"tilt", 0.0}};
  }

  uint64_t seed_;
  Rng rng_;
  SceneOptions options_;
  std::string variant_;
  int decoys_ = 0;
  std::string robot_;
  Vec2 room_ = Vec2(6, 6);
  TargetPlacement placement_ = TargetPlacement::kOpen;
  std::vector<GenFurniture> furniture_;
  std::vector<GenObject> objects_;
};

// Whether the scene can be solved: the target shows at least n_odds distinct face grids from the
// base regions once every other object is gone (the oracle's views), and every base region has
// room for the base.
// Version 2 asks more: the oracle, told the scene, removes the target within 30 steps (its
// ceiling exists: a pocket whose open side is narrower than the pose noise, walls whose faces
// cannot be confirmed, are drawn again).
bool Solvable(const std::string& text, int version) {
  auto parsed = ParseScenario(text);
  if (!parsed.ok()) return false;
  Simulator simulator(*parsed, 1);
  Oracle oracle(simulator);
  if (oracle.bases().empty()) return false;
  const int target = simulator.target_index();
  const uint64_t others = ~(uint64_t{1} << target);
  if (std::popcount(oracle.SeeableCorners(target, others)) < parsed->params.n_odds) return false;
  return version < 2 || OracleEpisodeSteps(*parsed, 1, 30) > 0;
}

}  // namespace

SceneOptions V2Options(uint64_t seed) {
  SceneOptions o;
  o.version = 2;
  if (seed > kHeldOutV2SeedBase && seed <= kHeldOutV2SeedBase + 60) {
    o.placement = static_cast<TargetPlacement>((seed - kHeldOutV2SeedBase - 1) / 20);
  }
  return o;
}

std::string GenerateScenarioJson(uint64_t seed, SceneSummary* summary,
                                 const SceneOptions& options) {
  // A few scenes are unsolvable as drawn (a target too high to see, no free base region): the
  // seed then draws again, deterministically.
  for (uint64_t attempt = 0;; ++attempt) {
    Generator generator(seed, attempt == 0 ? seed : HashMix(seed * 131 + attempt), options);
    json j = generator.Make(summary);
    if (attempt > 0) {
      j["description"] =
          j["description"].get<std::string>() + " (draw " + std::to_string(attempt + 1) + ")";
    }
    std::string text = j.dump(2) + "\n";
    if (Solvable(text, options.version) || attempt >= 50) return text;
  }
}

}  // namespace npfkct::sim
