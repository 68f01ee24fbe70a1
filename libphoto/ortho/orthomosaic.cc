// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/ortho/orthomosaic.h"

#include <gdal_priv.h>
#include <gdal_utils.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <unordered_map>

#include <opencv2/imgproc.hpp>
#include <opencv2/stitching/detail/blenders.hpp>
#include <opencv2/stitching/detail/exposure_compensate.hpp>
#include <opencv2/stitching/detail/seam_finders.hpp>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/base/parallel.h"
#include "libphoto/export/dsm.h"

namespace aerotri {
namespace {

constexpr int kZbufferScale = 4;  // z-buffer pixels per photo pixel, inverse

// The ortho grid: (x0, y0) the outer top-left corner, rows run south.
struct Grid {
  double x0 = 0, y0 = 0, res = 1;
  int width = 0, height = 0;
  double X(double i) const { return x0 + (i + 0.5) * res; }
  double Y(double j) const { return y0 - (j + 0.5) * res; }
};

// Surface height at (x, y): bilinear, or the cell's own value next to nodata.
std::optional<double> SurfaceAt(const Raster& s, double x, double y) {
  if (auto z = SampleRaster(s, x, y)) return z;
  const int cx = static_cast<int>(std::floor((x - s.geotransform[0]) / s.geotransform[1]));
  const int cy = static_cast<int>(std::floor((y - s.geotransform[3]) / s.geotransform[5]));
  if (cx < 0 || cy < 0 || cx >= s.width || cy >= s.height) return std::nullopt;
  const float v = s.at(cx, cy);
  if (v == static_cast<float>(s.nodata)) return std::nullopt;
  return v;
}

// One photo as the ortho sees it.
struct View {
  int image = -1;
  const Camera* camera = nullptr;
  Pose pose;
  // A rolling shutter's motion: each row seen from where the camera was.
  std::optional<RollingShutterMotion> shutter;
  double max_xn = 0, max_yn = 0;  // normalised coordinates inside the frame (with a margin)
  double sharpness = 0.0, weight = 1.0;
  cv::Rect bbox;                  // footprint on the coarse grid
  cv::Mat colour;                 // CV_32FC3 on bbox (coarse rendering)
  cv::Mat valid;                  // CV_8U on bbox: 255 in sight, 128 in frame but hidden
  cv::Mat cosine;                 // CV_32F on bbox: cos of the ray's angle from the vertical
  cv::Mat zbuffer;                // CV_32F, photo / kZbufferScale
  cv::Scalar gain{1.0, 1.0, 1.0};
  double depth_tolerance = 0.0;   // m, for the z-buffer test
};

// How a view sees a world point: not at all, in its frame but hidden behind
// the surface, or in its frame and in sight. A noisy or interpolated surface
// (canopy, water) can hide a point from every view; it is then drawn from
// the best view that has it in frame rather than left empty.
enum Sight : std::uint8_t { kOutOfFrame = 0, kHidden = 1, kVisible = 2 };

// Where a view's camera sees a world point (camera coordinates *pc, image
// *xy); false outside its frame's normalised bounds or behind it. A rolling
// shutter's row is found by fixed-point steps from the mid-readout pose's
// (each shrinks the error by the image's motion during one row, a hundredth
// of a pixel per pixel on a drone).
bool ViewPoint(const View& v, const Eigen::Vector3d& world, Eigen::Vector3d* pc, Eigen::Vector2d* xy) {
  Pose pose = v.pose;
  for (int step = 0;; ++step) {
    *pc = pose.CamFromWorld(world);
    if (pc->z() <= 0) return false;
    const double xn = pc->x() / pc->z(), yn = pc->y() / pc->z();
    if (std::abs(xn) > v.max_xn || std::abs(yn) > v.max_yn) return false;
    const Eigen::Vector2d next = v.camera->ImageFromNormalized({xn, yn});
    const bool settled = step > 0 && (next - *xy).squaredNorm() < 1e-6;
    *xy = next;
    if (!v.shutter || settled || step == 5) return true;
    pose.centre_in_world = v.pose.centre_in_world + v.shutter->CentreShift(xy->y(), v.camera->height);
  }
}

Sight Project(const View& v, const Eigen::Vector3d& world, Eigen::Vector2d* xy) {
  Eigen::Vector3d pc;
  if (!ViewPoint(v, world, &pc, xy)) return kOutOfFrame;
  if (xy->x() < 0 || xy->y() < 0 || xy->x() > v.camera->width - 1.0 || xy->y() > v.camera->height - 1.0) {
    return kOutOfFrame;
  }
  const int zx = static_cast<int>(xy->x() / kZbufferScale), zy = static_cast<int>(xy->y() / kZbufferScale);
  if (zx < v.zbuffer.cols && zy < v.zbuffer.rows) {
    const float front = v.zbuffer.at<float>(zy, zx);
    if (pc.z() > front + v.depth_tolerance + 2e-3 * pc.z()) return kHidden;
  }
  return kVisible;
}

// A view's score for a cell: visible views always beat hidden ones.
float Score(Sight sight, double cosine, double weight) {
  return sight == kOutOfFrame ? -1.0f : static_cast<float>(cosine * weight + (sight == kVisible ? 1.0 : 0.0));
}

cv::Vec3f Bilinear(const cv::Mat& bgr, double x, double y) {
  const int x0 = std::clamp(static_cast<int>(x), 0, bgr.cols - 2), y0 = std::clamp(static_cast<int>(y), 0, bgr.rows - 2);
  const float tx = static_cast<float>(x - x0), ty = static_cast<float>(y - y0);
  const cv::Vec3b a = bgr.at<cv::Vec3b>(y0, x0), b = bgr.at<cv::Vec3b>(y0, x0 + 1);
  const cv::Vec3b c = bgr.at<cv::Vec3b>(y0 + 1, x0), d = bgr.at<cv::Vec3b>(y0 + 1, x0 + 1);
  cv::Vec3f out;
  for (int k = 0; k < 3; ++k) out[k] = (a[k] * (1 - tx) + b[k] * tx) * (1 - ty) + (c[k] * (1 - tx) + d[k] * tx) * ty;
  return out;
}

// Decoded photos, least recently used dropped beyond a byte budget.
class ImageCache {
 public:
  ImageCache(std::function<cv::Mat(int)> load, std::size_t budget) : load_(std::move(load)), budget_(budget) {}
  std::shared_ptr<const cv::Mat> Get(int image) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const auto it = entries_.find(image);
      if (it != entries_.end()) {
        order_.splice(order_.begin(), order_, it->second.second);
        return it->second.first;
      }
    }
    auto loaded = std::make_shared<const cv::Mat>(load_(image));
    if (loaded->empty() || loaded->type() != CV_8UC3) {
      throw IoError("photo " + std::to_string(image), "cannot be read as an 8-bit colour image for the orthomosaic");
    }
    std::lock_guard<std::mutex> lock(mutex_);
    if (entries_.count(image)) return entries_[image].first;
    order_.push_front(image);
    entries_[image] = {loaded, order_.begin()};
    bytes_ += loaded->total() * loaded->elemSize();
    while (bytes_ > budget_ && order_.size() > 1) {
      const int old = order_.back();
      order_.pop_back();
      bytes_ -= entries_[old].first->total() * entries_[old].first->elemSize();
      entries_.erase(old);
    }
    return loaded;
  }

 private:
  std::function<cv::Mat(int)> load_;
  std::size_t budget_;
  std::size_t bytes_ = 0;
  std::mutex mutex_;
  std::list<int> order_;
  std::unordered_map<int, std::pair<std::shared_ptr<const cv::Mat>, std::list<int>::iterator>> entries_;
};

// The views' coarse renderings, occlusion buffers and footprints.
void PrepareView(View& v, const cv::Mat& photo, const Grid& coarse, const std::vector<Eigen::Vector3d>& world,
                 const std::vector<char>& has_surface) {
  const Camera& cam = *v.camera;
  // The frame in normalised coordinates, from its border's rays, widened 10 %.
  for (double t = 0; t <= 1.0; t += 0.125) {
    for (const Eigen::Vector2d& xy : {Eigen::Vector2d(t * (cam.width - 1), 0), Eigen::Vector2d(t * (cam.width - 1), cam.height - 1),
                                      Eigen::Vector2d(0, t * (cam.height - 1)), Eigen::Vector2d(cam.width - 1, t * (cam.height - 1))}) {
      if (const auto ray = cam.RayFromImage(xy)) {
        v.max_xn = std::max(v.max_xn, 1.1 * std::abs(ray->x() / ray->z()));
        v.max_yn = std::max(v.max_yn, 1.1 * std::abs(ray->y() / ray->z()));
      }
    }
  }
  cv::Mat grey, lap;
  cv::cvtColor(photo, grey, cv::COLOR_BGR2GRAY);
  cv::Laplacian(grey, lap, CV_32F);
  cv::Scalar mean, stddev;
  cv::meanStdDev(lap, mean, stddev);
  v.sharpness = stddev[0] * stddev[0];

  // Footprint: every 8th coarse cell, then the box around those in frame.
  v.zbuffer = cv::Mat();  // no occlusion test while finding the footprint
  int x_lo = coarse.width, y_lo = coarse.height, x_hi = -1, y_hi = -1;
  Eigen::Vector2d xy;
  const int step = 8;
  for (int j = 0; j < coarse.height; j += std::min(step, std::max(1, coarse.height - 1 - j))) {
    for (int i = 0; i < coarse.width; i += std::min(step, std::max(1, coarse.width - 1 - i))) {
      const size_t c = static_cast<size_t>(j) * coarse.width + i;
      if (!has_surface[c] || Project(v, world[c], &xy) == kOutOfFrame) continue;
      x_lo = std::min(x_lo, i), x_hi = std::max(x_hi, i), y_lo = std::min(y_lo, j), y_hi = std::max(y_hi, j);
    }
    if (j == coarse.height - 1) break;
  }
  if (x_hi < 0) return;
  v.bbox = cv::Rect(cv::Point(std::max(0, x_lo - step), std::max(0, y_lo - step)),
                    cv::Point(std::min(coarse.width, x_hi + step + 1), std::min(coarse.height, y_hi + step + 1)));

  // Occlusion buffer: the surface's coarse cells splatted at their depth.
  v.zbuffer = cv::Mat((cam.height + kZbufferScale - 1) / kZbufferScale, (cam.width + kZbufferScale - 1) / kZbufferScale,
                      CV_32F, cv::Scalar(std::numeric_limits<float>::infinity()));
  const double focal = cam.params.empty() ? 1000.0 : cam.params[0];
  for (int j = v.bbox.y; j < v.bbox.y + v.bbox.height; ++j) {
    for (int i = v.bbox.x; i < v.bbox.x + v.bbox.width; ++i) {
      const size_t c = static_cast<size_t>(j) * coarse.width + i;
      if (!has_surface[c]) continue;
      Eigen::Vector3d pc;
      Eigen::Vector2d at;
      if (!ViewPoint(v, world[c], &pc, &at)) continue;
      const Eigen::Vector2d p = at / kZbufferScale;
      const int half = static_cast<int>(std::ceil(0.5 * coarse.res * focal / pc.z() / kZbufferScale + 0.5));
      const int px = static_cast<int>(std::floor(p.x())), py = static_cast<int>(std::floor(p.y()));
      for (int y = std::max(0, py - half + 1); y <= std::min(v.zbuffer.rows - 1, py + half); ++y) {
        for (int x = std::max(0, px - half + 1); x <= std::min(v.zbuffer.cols - 1, px + half); ++x) {
          float& z = v.zbuffer.at<float>(y, x);
          z = std::min(z, static_cast<float>(pc.z()));
        }
      }
    }
  }
  // A ground cell hides behind its neighbour only by more than the coarse
  // grid's own relief step.
  v.depth_tolerance = 1.5 * coarse.res;

  v.colour = cv::Mat(v.bbox.size(), CV_32FC3, cv::Scalar(0, 0, 0));
  v.valid = cv::Mat(v.bbox.size(), CV_8U, cv::Scalar(0));
  v.cosine = cv::Mat(v.bbox.size(), CV_32F, cv::Scalar(0));
  for (int j = 0; j < v.bbox.height; ++j) {
    for (int i = 0; i < v.bbox.width; ++i) {
      const size_t c = static_cast<size_t>(j + v.bbox.y) * coarse.width + (i + v.bbox.x);
      if (!has_surface[c]) continue;
      const Sight sight = Project(v, world[c], &xy);
      if (sight == kOutOfFrame) continue;
      v.valid.at<std::uint8_t>(j, i) = sight == kVisible ? 255 : 128;
      v.colour.at<cv::Vec3f>(j, i) = Bilinear(photo, xy.x(), xy.y());
      const Eigen::Vector3d ray = v.pose.centre_in_world - world[c];
      v.cosine.at<float>(j, i) = static_cast<float>(ray.z() / ray.norm());
    }
  }
}

// World coordinates over a block of ortho cells: exact on a lattice at the
// block's lowest and highest surface heights, interpolated between (the
// CRS-to-world map is smooth over a few metres).
class BlockToWorld {
 public:
  BlockToWorld(const Grid& g, const cv::Rect& r, double z0, double z1, const CrsToWorld& to_world)
      : r_(r), z0_(z0), z1_(z1 > z0 + 1e-3 ? z1 : z0 + 1.0) {
    nx_ = (r.width + kStep - 1) / kStep + 1;
    ny_ = (r.height + kStep - 1) / kStep + 1;
    lo_.resize(static_cast<size_t>(nx_) * ny_);
    hi_.resize(lo_.size());
    for (int b = 0; b < ny_; ++b) {
      for (int a = 0; a < nx_; ++a) {
        const double x = g.X(r.x + a * kStep), y = g.Y(r.y + b * kStep);
        lo_[static_cast<size_t>(b) * nx_ + a] = to_world({x, y, z0_});
        hi_[static_cast<size_t>(b) * nx_ + a] = to_world({x, y, z1_});
      }
    }
  }
  Eigen::Vector3d At(int i, int j, double z) const {  // cell (i, j) of the grid
    const double fa = static_cast<double>(i - r_.x) / kStep, fb = static_cast<double>(j - r_.y) / kStep;
    const int a = std::min(static_cast<int>(fa), nx_ - 2), b = std::min(static_cast<int>(fb), ny_ - 2);
    const double ta = fa - a, tb = fb - b;
    auto lerp = [&](const std::vector<Eigen::Vector3d>& v) {
      const auto& p00 = v[static_cast<size_t>(b) * nx_ + a];
      const auto& p10 = v[static_cast<size_t>(b) * nx_ + a + 1];
      const auto& p01 = v[static_cast<size_t>(b + 1) * nx_ + a];
      const auto& p11 = v[static_cast<size_t>(b + 1) * nx_ + a + 1];
      return Eigen::Vector3d((p00 * (1 - ta) + p10 * ta) * (1 - tb) + (p01 * (1 - ta) + p11 * ta) * tb);
    };
    const double t = (z - z0_) / (z1_ - z0_);
    const Eigen::Vector3d lo = lerp(lo_);
    return lo + t * (lerp(hi_) - lo);
  }

 private:
  static constexpr int kStep = 8;
  cv::Rect r_;
  double z0_, z1_;
  int nx_ = 0, ny_ = 0;
  std::vector<Eigen::Vector3d> lo_, hi_;
};

}  // namespace

namespace {

// The deliverable's compression, upper case; InvalidArgument for another.
std::string Compression(const OrthoOptions& o) {
  std::string compress = o.compress;
  std::transform(compress.begin(), compress.end(), compress.begin(), ::toupper);
  if (compress != "JPEG" && compress != "DEFLATE") {
    throw InvalidArgument("orthomosaic: compression '" + o.compress + "' (expected JPEG or DEFLATE)");
  }
  return compress;
}

// The deliverable from the drawn RGBA raster (a GeoTIFF, or a VRT of bands):
// a Cloud-Optimised GeoTIFF, or a tiled GeoTIFF with overviews; atomically.
void WriteDeliverable(const std::filesystem::path& source, const OrthoOptions& o, const std::filesystem::path& path) {
  const std::string compress = Compression(o);
  const std::filesystem::path tmp = TemporaryPathFor(path);
  std::vector<std::string> args;
  const std::string quality = "QUALITY=" + std::to_string(o.jpeg_quality);
  if (o.cog) {
    args = {"-of", "COG", "-co", "COMPRESS=" + compress, "-co", "BIGTIFF=IF_SAFER", "-co", "OVERVIEWS=AUTO"};
    if (compress == "JPEG") args.insert(args.end(), {"-co", quality});
  } else if (compress == "JPEG") {
    args = {"-of", "GTiff", "-b", "1", "-b", "2", "-b", "3", "-mask", "4", "-co", "TILED=YES", "-co", "COMPRESS=JPEG",
            "-co", "PHOTOMETRIC=YCBCR", "-co", "JPEG_" + quality, "-co", "BIGTIFF=IF_SAFER"};
  } else {
    args = {"-of", "GTiff", "-co", "TILED=YES", "-co", "COMPRESS=DEFLATE", "-co", "BIGTIFF=IF_SAFER"};
  }
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  GDALTranslateOptions* topts = GDALTranslateOptionsNew(argv.data(), nullptr);
  GDALDatasetH src = GDALOpen(source.string().c_str(), GA_ReadOnly);
  int usage_error = 0;
  GDALDatasetH dst = src ? GDALTranslate(tmp.string().c_str(), src, topts, &usage_error) : nullptr;
  GDALTranslateOptionsFree(topts);
  const int width = src ? GDALGetRasterXSize(src) : 0;
  if (src) GDALClose(src);
  if (!dst) {
    std::filesystem::remove(tmp);
    throw IoError(tmp.string(), std::string("GDAL could not write the orthomosaic: ") + CPLGetLastErrorMsg());
  }
  if (!o.cog) {
    int levels[] = {2, 4, 8, 16, 32};
    int n = 0;
    while (n < 5 && (width >> (n + 1)) >= 256) ++n;
    if (n > 0 && GDALBuildOverviews(dst, "AVERAGE", n, levels, 0, nullptr, nullptr, nullptr) != CE_None) {
      GDALClose(dst);
      std::filesystem::remove(tmp);
      throw IoError(tmp.string(), std::string("cannot build overviews: ") + CPLGetLastErrorMsg());
    }
  }
  GDALClose(dst);
  std::filesystem::rename(tmp, path);
}

}  // namespace

namespace {

void CheckOrthoOptions(const OrthoOptions& o) {
  if (!(o.resolution_m > 0)) throw InvalidArgument("orthomosaic: the resolution must be > 0");
  if (o.tile_size < 64 || o.tile_margin < 0 || o.seam_cell_factor < 1 || o.blend_bands < 0) {
    throw InvalidArgument("orthomosaic: tile size >= 64, margin >= 0, seam factor >= 1, bands >= 0");
  }
  if (o.share_count < 1 || o.share_index < 0 || o.share_index >= o.share_count) {
    throw InvalidArgument("orthomosaic: share " + std::to_string(o.share_index + 1) + " of " +
                          std::to_string(o.share_count));
  }
  Compression(o);  // checked before the work
}

// The ortho grid over the surface's extent with data, at the ortho
// resolution, and the seam grid: coarse enough to stay within 16 M cells.
struct OrthoGrids {
  Grid grid, coarse;
  int factor = 1;
};

OrthoGrids MakeGrids(const Raster& surface, const OrthoOptions& o) {
  const float nd = static_cast<float>(surface.nodata);
  double min_x = 1e300, max_x = -1e300, min_y = 1e300, max_y = -1e300;
  for (int y = 0; y < surface.height; ++y) {
    for (int x = 0; x < surface.width; ++x) {
      if (surface.at(x, y) == nd) continue;
      min_x = std::min(min_x, surface.geotransform[0] + x * surface.geotransform[1]);
      max_x = std::max(max_x, surface.geotransform[0] + (x + 1) * surface.geotransform[1]);
      max_y = std::max(max_y, surface.geotransform[3] + y * surface.geotransform[5]);
      min_y = std::min(min_y, surface.geotransform[3] + (y + 1) * surface.geotransform[5]);
    }
  }
  if (max_x < min_x) throw InvalidArgument("orthomosaic: the surface has no data");
  OrthoGrids g;
  Grid& grid = g.grid;
  grid.res = o.resolution_m;
  grid.x0 = std::floor(min_x / grid.res) * grid.res;
  grid.y0 = std::ceil(max_y / grid.res) * grid.res;
  grid.width = static_cast<int>(std::ceil((max_x - grid.x0) / grid.res));
  grid.height = static_cast<int>(std::ceil((grid.y0 - min_y) / grid.res));
  if (static_cast<double>(grid.width) * grid.height > 2.5e9) {
    throw InvalidArgument("orthomosaic: " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                          " cells is too large; choose a coarser --ortho-resolution");
  }
  g.factor = o.seam_cell_factor;
  while (static_cast<double>(grid.width) * grid.height / (g.factor * g.factor) > 16e6) ++g.factor;
  g.coarse.res = grid.res * g.factor;
  g.coarse.x0 = grid.x0;
  g.coarse.y0 = grid.y0;
  g.coarse.width = (grid.width + g.factor - 1) / g.factor;
  g.coarse.height = (grid.height + g.factor - 1) / g.factor;
  return g;
}

// The surface with its holes interpolated (fill_surface_holes); *interpolated
// counts the cells filled.
Raster FillSurface(const Raster& surface_in, const OrthoOptions& o, long long* interpolated) {
  Raster surface = surface_in;
  *interpolated = 0;
  if (!o.fill_surface_holes) return surface;
  const float nd = static_cast<float>(surface.nodata);
  const std::vector<float> filled = FilledNodata(surface, surface.width + surface.height + 1.0, o.work_dir, 20);
  for (size_t k = 0; k < filled.size(); ++k) *interpolated += surface.values[k] == nd && filled[k] != nd;
  surface.values = filled;
  return surface;
}

// World coordinates of the coarse cells (and which have a surface).
void CoarseWorld(const Raster& surface, const Grid& coarse, const CrsToWorldFactory& to_world_factory,
                 unsigned threads, std::vector<Eigen::Vector3d>* world, std::vector<char>* has_surface) {
  world->assign(static_cast<size_t>(coarse.width) * coarse.height, Eigen::Vector3d::Zero());
  has_surface->assign(world->size(), 0);
  ParallelFor(threads, threads, [&](size_t t) {
    const CrsToWorld to_world = to_world_factory();  // one per thread
    for (size_t j = t; j < static_cast<size_t>(coarse.height); j += threads) {
      for (int i = 0; i < coarse.width; ++i) {
        const size_t c = j * coarse.width + i;
        const auto z = SurfaceAt(surface, coarse.X(i), coarse.Y(static_cast<double>(j)));
        if (!z) continue;
        (*world)[c] = to_world({coarse.X(i), coarse.Y(static_cast<double>(j)), *z});
        (*has_surface)[c] = 1;
      }
    }
  });
}

// Every registered photo as a view: its coarse rendering, occlusion buffer
// and footprint, weighted by its sharpness against the median.
std::vector<View> PrepareViews(const SparseModel& model, const std::function<cv::Mat(int image)>& load_image,
                               const Grid& coarse, const std::vector<Eigen::Vector3d>& world,
                               const std::vector<char>& has_surface, unsigned threads,
                               const ProgressCallback& progress) {
  std::vector<View> views;
  for (size_t k = 0; k < model.images.size(); ++k) {
    const Image& image = model.images[k];
    if (!image.registered) continue;
    View v;
    v.image = static_cast<int>(k);
    v.camera = &model.cameras.at(image.camera);
    v.pose = image.pose;
    if (image.rolling_shutter && image.rolling_shutter->readout_time_s != 0.0) v.shutter = image.rolling_shutter;
    views.push_back(std::move(v));
  }
  if (views.empty()) throw InvalidArgument("orthomosaic: no registered photo");
  std::atomic<int> prepared{0};
  std::mutex progress_mutex;
  ParallelFor(views.size(), threads, [&](size_t k) {
    const cv::Mat photo = load_image(views[k].image);
    if (photo.empty() || photo.type() != CV_8UC3) {
      throw IoError(model.images[views[k].image].name, "cannot be read as an 8-bit colour image for the orthomosaic");
    }
    PrepareView(views[k], photo, coarse, world, has_surface);
    const int done = ++prepared;
    std::lock_guard<std::mutex> lock(progress_mutex);
    ReportProgress(progress, 0.3 * done / views.size(),
                   "orthomosaic: views " + std::to_string(done) + "/" + std::to_string(views.size()));
  });
  std::vector<double> sharpness;
  for (const View& v : views) {
    if (v.sharpness > 0) sharpness.push_back(v.sharpness);
  }
  double median_sharpness = 1.0;
  if (!sharpness.empty()) {
    std::nth_element(sharpness.begin(), sharpness.begin() + sharpness.size() / 2, sharpness.end());
    median_sharpness = sharpness[sharpness.size() / 2];
  }
  for (View& v : views) v.weight = 0.9 + 0.1 * std::min(1.0, v.sharpness / std::max(1e-9, median_sharpness));
  return views;
}

// The best view per coarse cell.
cv::Mat BestViewLabels(const std::vector<View>& views, const Grid& coarse) {
  cv::Mat label(coarse.height, coarse.width, CV_32S, cv::Scalar(-1));
  cv::Mat best(coarse.height, coarse.width, CV_32F, cv::Scalar(-1.0f));
  for (size_t k = 0; k < views.size(); ++k) {
    const View& v = views[k];
    if (v.bbox.empty()) continue;
    for (int j = 0; j < v.bbox.height; ++j) {
      for (int i = 0; i < v.bbox.width; ++i) {
        const std::uint8_t seen = v.valid.at<std::uint8_t>(j, i);
        if (!seen) continue;
        const float s = Score(seen == 255 ? kVisible : kHidden, v.cosine.at<float>(j, i), v.weight);
        float& b = best.at<float>(j + v.bbox.y, i + v.bbox.x);
        if (s > b) {
          b = s;
          label.at<int>(j + v.bbox.y, i + v.bbox.x) = static_cast<int>(k);
        }
      }
    }
  }
  return label;
}

// Seams: the partition widened by a band, cut where the views agree
// (OpenCV's graph-cut seam finder); label: each coarse cell's view after.
struct Seams {
  std::vector<int> views;
  std::vector<cv::Point> corners;
  cv::Mat label;
};

Seams FindSeams(const std::vector<View>& views, const cv::Mat& label, const Grid& coarse, const OrthoOptions& o,
                const ProgressCallback& progress) {
  Seams seams;
  std::vector<cv::UMat> seam_images, seam_masks;
  const cv::Mat band = cv::getStructuringElement(
      cv::MORPH_ELLIPSE, cv::Size(2 * o.seam_band_cells + 1, 2 * o.seam_band_cells + 1));
  for (size_t k = 0; k < views.size(); ++k) {
    const View& v = views[k];
    if (v.bbox.empty()) continue;
    cv::Mat own = label(v.bbox) == static_cast<int>(k);
    if (cv::countNonZero(own) == 0) continue;
    cv::Mat widened;
    cv::dilate(own, widened, band);
    widened &= v.valid > 0;
    seams.views.push_back(static_cast<int>(k));
    seam_images.push_back(v.colour.getUMat(cv::ACCESS_READ));  // a view of the rendering, not a copy
    seam_masks.push_back(widened.getUMat(cv::ACCESS_READ).clone());
    seams.corners.push_back(v.bbox.tl());
  }
  ReportProgress(progress, 0.32, "orthomosaic: seams (" + std::to_string(seams.views.size()) + " photos)");
  if (seams.views.size() > 1 && o.seam_band_cells > 0) {
    cv::detail::GraphCutSeamFinder finder(cv::detail::GraphCutSeamFinderBase::COST_COLOR_GRAD);
    finder.find(seam_images, seams.corners, seam_masks);
  }
  seams.label = cv::Mat(coarse.height, coarse.width, CV_32S, cv::Scalar(-1));
  for (size_t s = 0; s < seams.views.size(); ++s) {
    const int k = seams.views[s];
    const cv::Mat mask = seam_masks[s].getMat(cv::ACCESS_READ);
    const cv::Rect& r = views[k].bbox;
    for (int j = 0; j < r.height; ++j) {
      for (int i = 0; i < r.width; ++i) {
        if (!mask.at<std::uint8_t>(j, i)) continue;
        int& l = seams.label.at<int>(j + r.y, i + r.x);
        if (l < 0 || label.at<int>(j + r.y, i + r.x) == k) l = k;
      }
    }
  }
  for (int j = 0; j < coarse.height; ++j) {
    for (int i = 0; i < coarse.width; ++i) {
      if (seams.label.at<int>(j, i) < 0) seams.label.at<int>(j, i) = label.at<int>(j, i);
    }
  }
  return seams;
}

// Exposure: per-channel gains over the overlaps (OpenCV's compensator).
void CompensateExposure(const Seams& seams, const OrthoOptions& o, std::vector<View>* views) {
  if (!o.exposure_compensation || seams.views.size() <= 1) return;
  std::vector<cv::UMat> images8;
  std::vector<std::pair<cv::UMat, std::uint8_t>> valid_masks;
  for (int k : seams.views) {
    cv::Mat c8;
    (*views)[k].colour.convertTo(c8, CV_8UC3);
    images8.push_back(c8.getUMat(cv::ACCESS_READ).clone());
    const cv::Mat visible = (*views)[k].valid == 255;  // gains from what each view really sees
    valid_masks.emplace_back(visible.getUMat(cv::ACCESS_READ).clone(), 255);
  }
  cv::detail::ChannelsCompensator compensator;
  compensator.feed(seams.corners, images8, valid_masks);
  const std::vector<cv::Scalar> gains = compensator.gains();
  for (size_t s = 0; s < seams.views.size() && s < gains.size(); ++s) (*views)[seams.views[s]].gain = gains[s];
}

// What drawing a tile reads.
struct TileInputs {
  const OrthoGrids& grids;
  const Raster& surface;     // holes filled
  const Raster& surface_in;  // as given: which cells have data of their own
  const CrsToWorldFactory& to_world_factory;
  const std::vector<View>& views;
  const cv::Mat& seam_label;
  const OrthoOptions& o;
  ImageCache& cache;
  std::vector<std::atomic<char>>& used;
};

// The region's cells: surface heights (NaN without) and world coordinates.
struct RegionCells {
  cv::Rect region;
  cv::Mat z;           // CV_32F
  cv::Mat world;       // CV_64FC3
  bool any = false;
};

RegionCells CellsOf(const TileInputs& in, const cv::Rect& region) {
  const Grid& grid = in.grids.grid;
  RegionCells cells;
  cells.region = region;
  cells.z = cv::Mat(region.size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  double z_lo = 1e300, z_hi = -1e300;
  for (int j = 0; j < region.height; ++j) {
    for (int i = 0; i < region.width; ++i) {
      const auto h = SurfaceAt(in.surface, grid.X(region.x + i), grid.Y(region.y + j));
      if (!h) continue;
      cells.z.at<float>(j, i) = static_cast<float>(*h);
      z_lo = std::min(z_lo, *h), z_hi = std::max(z_hi, *h);
    }
  }
  cells.any = z_hi >= z_lo;
  if (!cells.any) return cells;
  const BlockToWorld block(grid, region, z_lo, z_hi, in.to_world_factory());
  cells.world = cv::Mat(region.size(), CV_64FC3);
  for (int j = 0; j < region.height; ++j) {
    for (int i = 0; i < region.width; ++i) {
      const float h = cells.z.at<float>(j, i);
      if (std::isnan(h)) continue;
      const Eigen::Vector3d w = block.At(region.x + i, region.y + j, h);
      cells.world.at<cv::Vec3d>(j, i) = cv::Vec3d(w.x(), w.y(), w.z());
    }
  }
  return cells;
}

// The candidate views of a region (every view whose footprint meets it: the
// same views for a cell whichever tile draws it, so that tiles agree at
// their borders), each with its resampling maps and scores.
struct Candidates {
  std::vector<int> views;
  std::vector<cv::Mat> map_x, map_y, score;
};

Candidates ProjectCandidates(const TileInputs& in, const RegionCells& cells) {
  const cv::Rect& region = cells.region;
  const int factor = in.grids.factor;
  std::set<int> candidates;
  const cv::Rect coarse_region =
      cv::Rect(region.x / factor - 1, region.y / factor - 1, region.width / factor + 3, region.height / factor + 3) &
      cv::Rect(0, 0, in.grids.coarse.width, in.grids.coarse.height);
  for (size_t k = 0; k < in.views.size(); ++k) {
    if (!in.views[k].bbox.empty() && (in.views[k].bbox & coarse_region).area() > 0) {
      candidates.insert(static_cast<int>(k));
    }
  }
  Candidates c;
  c.views.assign(candidates.begin(), candidates.end());
  c.map_x.resize(c.views.size());
  c.map_y.resize(c.views.size());
  c.score.resize(c.views.size());
  for (size_t n = 0; n < c.views.size(); ++n) {
    const View& v = in.views[c.views[n]];
    c.map_x[n] = cv::Mat(region.size(), CV_32F, cv::Scalar(-1.0f));
    c.map_y[n] = cv::Mat(region.size(), CV_32F, cv::Scalar(-1.0f));
    c.score[n] = cv::Mat(region.size(), CV_32F, cv::Scalar(-1.0f));
    Eigen::Vector2d xy;
    for (int j = 0; j < region.height; ++j) {
      for (int i = 0; i < region.width; ++i) {
        if (std::isnan(cells.z.at<float>(j, i))) continue;
        const cv::Vec3d& cw = cells.world.at<cv::Vec3d>(j, i);
        const Eigen::Vector3d w(cw[0], cw[1], cw[2]);
        const Sight sight = Project(v, w, &xy);
        if (sight == kOutOfFrame) continue;
        c.map_x[n].at<float>(j, i) = static_cast<float>(xy.x());
        c.map_y[n].at<float>(j, i) = static_cast<float>(xy.y());
        const Eigen::Vector3d ray = v.pose.centre_in_world - w;
        c.score[n].at<float>(j, i) = Score(sight, ray.z() / ray.norm(), v.weight);
      }
    }
  }
  return c;
}

// Each cell's view (an index into the candidates): its coarse cell's, else
// the best that sees it; -1 where none.
cv::Mat AssignOwners(const TileInputs& in, const RegionCells& cells, const Candidates& c) {
  const cv::Rect& region = cells.region;
  const Grid& coarse = in.grids.coarse;
  const int factor = in.grids.factor;
  cv::Mat owner(region.size(), CV_32S, cv::Scalar(-1));
  std::vector<int> index_of(in.views.size(), -1);
  for (size_t n = 0; n < c.views.size(); ++n) index_of[c.views[n]] = static_cast<int>(n);
  for (int j = 0; j < region.height; ++j) {
    for (int i = 0; i < region.width; ++i) {
      if (std::isnan(cells.z.at<float>(j, i))) continue;
      const int l = in.seam_label.at<int>(std::min(coarse.height - 1, (region.y + j) / factor),
                                          std::min(coarse.width - 1, (region.x + i) / factor));
      if (l >= 0 && index_of[l] >= 0 && c.score[index_of[l]].at<float>(j, i) >= 1.0f) {  // in sight
        owner.at<int>(j, i) = index_of[l];
        continue;
      }
      float b = -1.0f;
      for (size_t n = 0; n < c.views.size(); ++n) {
        if (c.score[n].at<float>(j, i) > b) b = c.score[n].at<float>(j, i), owner.at<int>(j, i) = static_cast<int>(n);
      }
    }
  }
  return owner;
}

// Each owning view resampled, its exposure gain applied, and the owners
// blended across their seams (OpenCV's multi-band blender).
cv::Mat ResampleAndBlend(const TileInputs& in, const cv::Rect& region, const Candidates& c, const cv::Mat& owner) {
  std::vector<int> owners;
  for (size_t n = 0; n < c.views.size(); ++n) {
    if (cv::countNonZero(owner == static_cast<int>(n)) > 0) owners.push_back(static_cast<int>(n));
  }
  cv::Mat blended(region.size(), CV_8UC3, cv::Scalar(0, 0, 0));
  if (owners.empty()) return blended;
  const bool blend = owners.size() > 1 && in.o.blend_bands > 0;
  cv::detail::MultiBandBlender blender(false, in.o.blend_bands, CV_16S);
  if (blend) blender.prepare(cv::Rect(0, 0, region.width, region.height));
  for (int n : owners) {
    const View& v = in.views[c.views[n]];
    in.used[c.views[n]] = 1;
    const auto photo = in.cache.Get(v.image);
    cv::Mat patch;
    cv::remap(*photo, patch, c.map_x[n], c.map_y[n], cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    cv::Mat patch16;
    patch.convertTo(patch16, CV_16SC3);
    if (v.gain != cv::Scalar(1.0, 1.0, 1.0)) {
      cv::Mat f;
      patch.convertTo(f, CV_32FC3);
      cv::multiply(f, v.gain, f);
      f.convertTo(patch16, CV_16SC3);
    }
    const cv::Mat mask = owner == n;
    if (blend) {
      blender.feed(patch16, mask, cv::Point(0, 0));
    } else {
      cv::Mat p8;
      patch16.convertTo(p8, CV_8UC3);
      p8.copyTo(blended, mask);
    }
  }
  if (blend) {
    cv::Mat dst, dst_mask;
    blender.blend(dst, dst_mask);
    dst(cv::Rect(0, 0, region.width, region.height)).convertTo(blended, CV_8UC3);
  }
  return blended;
}

// One tile: RGBA over its inner cells; the cells with a surface of their
// own (not the holes filled for drawing) and those drawn, counted.
struct DrawnTile {
  cv::Mat rgba;
  long long with_surface = 0, filled = 0;
};

DrawnTile DrawTile(const TileInputs& in, const cv::Rect& inner) {
  const Grid& grid = in.grids.grid;
  const int M = in.o.tile_margin;
  const cv::Rect region = cv::Rect(inner.x - M, inner.y - M, inner.width + 2 * M, inner.height + 2 * M) &
                          cv::Rect(0, 0, grid.width, grid.height);
  DrawnTile tile;
  tile.rgba = cv::Mat(inner.size(), CV_8UC4, cv::Scalar(0, 0, 0, 0));
  const RegionCells cells = CellsOf(in, region);
  if (!cells.any) return tile;
  const Candidates candidates = ProjectCandidates(in, cells);
  const cv::Mat owner = AssignOwners(in, cells, candidates);
  const cv::Mat blended = ResampleAndBlend(in, region, candidates, owner);
  const Raster& s = in.surface_in;
  const float nd = static_cast<float>(s.nodata);
  const cv::Point off = inner.tl() - region.tl();
  for (int j = 0; j < inner.height; ++j) {
    for (int i = 0; i < inner.width; ++i) {
      if (std::isnan(cells.z.at<float>(j + off.y, i + off.x))) continue;
      const bool owned = owner.at<int>(j + off.y, i + off.x) >= 0;
      const int sx = static_cast<int>(std::floor((grid.X(inner.x + i) - s.geotransform[0]) / s.geotransform[1]));
      const int sy = static_cast<int>(std::floor((grid.Y(inner.y + j) - s.geotransform[3]) / s.geotransform[5]));
      if (sx >= 0 && sy >= 0 && sx < s.width && sy < s.height && s.at(sx, sy) != nd) {
        ++tile.with_surface;
        tile.filled += owned;
      }
      if (!owned) continue;
      const cv::Vec3b bgr = blended.at<cv::Vec3b>(j + off.y, i + off.x);
      tile.rgba.at<cv::Vec4b>(j, i) = cv::Vec4b(bgr[2], bgr[1], bgr[0], 255);
    }
  }
  return tile;
}

// The RGBA GeoTIFF a band is drawn into, tile by tile.
std::unique_ptr<GDALDataset> CreateBand(const std::filesystem::path& build, const Grid& grid, int band_y,
                                        int band_height, const Raster& surface, const OrthoOptions& o) {
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  const char* create_opts[] = {"TILED=YES", "BLOCKXSIZE=512", "BLOCKYSIZE=512", "COMPRESS=DEFLATE",
                               "BIGTIFF=IF_SAFER", "PHOTOMETRIC=RGB", "ALPHA=YES", nullptr};
  std::unique_ptr<GDALDataset> out(
      gtiff->Create(build.string().c_str(), grid.width, band_height, 4, GDT_Byte, const_cast<char**>(create_opts)));
  if (!out) throw IoError(build.string(), std::string("cannot create: ") + CPLGetLastErrorMsg());
  double gt[6] = {grid.x0, grid.res, 0.0, grid.y0 - band_y * grid.res, 0.0, -grid.res};
  out->SetGeoTransform(gt);
  if (!surface.wkt.empty()) out->SetProjection(surface.wkt.c_str());
  for (const auto& [key, value] : o.metadata) out->SetMetadataItem(key.c_str(), value.c_str());
  out->GetRasterBand(4)->SetColorInterpretation(GCI_AlphaBand);
  return out;
}

// The tile rows this call draws: all of them, or a share's run.
struct TileBand {
  int tiles_x = 0, band_y = 0, band_height = 0;
  size_t first_tile = 0, tiles = 0;
};

TileBand BandOf(const Grid& grid, const OrthoOptions& o) {
  const int T = o.tile_size;
  TileBand b;
  b.tiles_x = (grid.width + T - 1) / T;
  const int tiles_y = (grid.height + T - 1) / T;
  const int row0 = static_cast<int>(static_cast<long long>(tiles_y) * o.share_index / o.share_count);
  const int row1 = static_cast<int>(static_cast<long long>(tiles_y) * (o.share_index + 1) / o.share_count);
  b.band_y = row0 * T;
  b.band_height = std::min(grid.height, row1 * T) - b.band_y;
  b.first_tile = static_cast<size_t>(row0) * b.tiles_x;
  b.tiles = static_cast<size_t>(b.tiles_x) * (row1 - row0);
  return b;
}

}  // namespace

void WriteOrthomosaic(const SparseModel& model, const std::function<cv::Mat(int image)>& load_image,
                      const Raster& surface_in, const CrsToWorldFactory& to_world_factory, const OrthoOptions& o,
                      const std::filesystem::path& path, const ProgressCallback& progress, OrthoSummary* summary) {
  CheckOrthoOptions(o);
  const unsigned threads = ThreadCount(o.num_threads);
  const OrthoGrids grids = MakeGrids(surface_in, o);
  const Grid& grid = grids.grid;
  long long interpolated = 0;
  const Raster surface = FillSurface(surface_in, o, &interpolated);

  ReportProgress(progress, 0.0, "orthomosaic: views and occlusion");
  std::vector<Eigen::Vector3d> world;
  std::vector<char> has_surface;
  CoarseWorld(surface, grids.coarse, to_world_factory, threads, &world, &has_surface);
  std::vector<View> views = PrepareViews(model, load_image, grids.coarse, world, has_surface, threads, progress);
  Seams seams = FindSeams(views, BestViewLabels(views, grids.coarse), grids.coarse, o, progress);
  CompensateExposure(seams, o, &views);
  // The coarse renderings have done their work.
  for (View& v : views) {
    v.colour.release();
    v.cosine.release();
  }

  const TileBand band = BandOf(grid, o);
  if (band.band_height <= 0) {  // an empty share (more shares than tile rows): no band
    if (summary) {
      *summary = OrthoSummary();
      summary->width = grid.width;
      summary->height = grid.height;
      summary->surface_cells_interpolated = interpolated;
      summary->band_y = band.band_y;
    }
    ReportProgress(progress, 1.0, "orthomosaic: no tile rows in this share");
    return;
  }

  GDALAllRegister();
  const std::filesystem::path work_dir = o.work_dir.empty() ? path.parent_path() : o.work_dir;
  // A temporary name (an interrupted run's is swept away), in the work folder.
  const std::filesystem::path build = work_dir / (TemporaryPathFor(path).filename().string() + ".building.tif");
  std::unique_ptr<GDALDataset> out = CreateBand(build, grid, band.band_y, band.band_height, surface, o);
  std::mutex write_mutex;
  ImageCache cache(load_image, o.image_cache_bytes);
  std::atomic<long long> cells_surface{0}, cells_filled{0};
  std::vector<std::atomic<char>> used(views.size());
  for (auto& u : used) u = 0;
  const TileInputs inputs{grids, surface, surface_in, to_world_factory, views, seams.label, o, cache, used};
  std::atomic<int> tiles_done{0};
  ParallelFor(band.tiles, threads, [&](size_t share_tile) {
    const int T = o.tile_size;
    const size_t t = band.first_tile + share_tile;
    const cv::Rect tile(static_cast<int>(t % band.tiles_x) * T, static_cast<int>(t / band.tiles_x) * T, T, T);
    const cv::Rect inner = tile & cv::Rect(0, 0, grid.width, grid.height);
    DrawnTile drawn = DrawTile(inputs, inner);
    cells_surface += drawn.with_surface;
    cells_filled += drawn.filled;
    std::lock_guard<std::mutex> lock(write_mutex);
    int bands[4] = {1, 2, 3, 4};
    if (out->RasterIO(GF_Write, inner.x, inner.y - band.band_y, inner.width, inner.height, drawn.rgba.data,
                      inner.width, inner.height, GDT_Byte, 4, bands, 4, static_cast<GSpacing>(drawn.rgba.step), 1,
                      nullptr) != CE_None) {
      throw IoError(build.string(), std::string("cannot write a tile: ") + CPLGetLastErrorMsg());
    }
    const int done = ++tiles_done;
    if (!ReportProgress(progress, 0.35 + 0.55 * done / band.tiles,
                        "orthomosaic: tile " + std::to_string(done) + "/" + std::to_string(band.tiles))) {
      throw InvalidArgument("orthomosaic: cancelled");
    }
  });
  out->FlushCache();
  out.reset();

  std::vector<int> images;
  for (size_t k = 0; k < views.size(); ++k) {
    if (used[k]) images.push_back(views[k].image);
  }
  if (summary) {
    summary->width = grid.width;
    summary->height = grid.height;
    summary->tiles = static_cast<int>(band.tiles);
    summary->images_used = static_cast<int>(images.size());
    summary->images = images;
    summary->cells_with_surface = cells_surface;
    summary->cells_filled = cells_filled;
    summary->filled_fraction = cells_surface > 0 ? static_cast<double>(cells_filled) / cells_surface : 0.0;
    summary->surface_cells_interpolated = interpolated;
    summary->band_y = band.band_y;
    summary->band_height = band.band_height;
  }
  if (o.share_count > 1) {  // a share's band, for AssembleOrthomosaic
    std::filesystem::rename(build, path);
    ReportProgress(progress, 1.0, "orthomosaic: band done");
    return;
  }
  // The deliverable: a Cloud-Optimised GeoTIFF, or a tiled GeoTIFF with overviews.
  ReportProgress(progress, 0.92, "orthomosaic: " + std::string(o.cog ? "Cloud-Optimised GeoTIFF" : "overviews"));
  WriteDeliverable(build, o, path);
  std::filesystem::remove(build);
  ReportProgress(progress, 1.0, "orthomosaic: done");
}

void AssembleOrthomosaic(const std::vector<std::filesystem::path>& bands, const OrthoOptions& o,
                         const std::filesystem::path& path) {
  if (bands.empty()) throw InvalidArgument("orthomosaic: no band to assemble");
  Compression(o);
  GDALAllRegister();
  const std::filesystem::path work_dir = o.work_dir.empty() ? path.parent_path() : o.work_dir;
  const std::filesystem::path vrt = work_dir / (TemporaryPathFor(path).filename().string() + ".bands.vrt");
  std::vector<std::string> names;
  for (const auto& b : bands) names.push_back(b.string());
  std::vector<const char*> inputs;
  for (const auto& n : names) inputs.push_back(n.c_str());
  int usage_error = 0;
  GDALDatasetH mosaic = GDALBuildVRT(vrt.string().c_str(), static_cast<int>(inputs.size()), nullptr, inputs.data(),
                                     nullptr, &usage_error);
  if (!mosaic) throw IoError(vrt.string(), std::string("GDAL could not join the bands: ") + CPLGetLastErrorMsg());
  GDALClose(mosaic);
  try {
    WriteDeliverable(vrt, o, path);
  } catch (...) {
    std::filesystem::remove(vrt);
    throw;
  }
  std::filesystem::remove(vrt);
}

}  // namespace aerotri
