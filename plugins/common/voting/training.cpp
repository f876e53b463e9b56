// furnihost::voting: the training parts of the catalog's views (features, offsets to the object
// centre, heights).
#include "voting/voting.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>

#include "furnihost/error.hpp"
#include "furnihost/geometry.hpp"

namespace furnihost::voting {

namespace {

float Median(std::vector<float> v) {
  if (v.empty()) return 0.f;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5f * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

TrainingParts CollectTrainingParts(const std::vector<TrainingView>& views) {
  if (views.empty()) throw StageError("no training views to learn from");
  TrainingParts out;
  std::set<std::string> class_names, model_names;
  for (const auto& v : views) {
    if (v.cls.empty()) throw StageError("training view of model '" + v.model_id + "' has no class");
    class_names.insert(v.cls);
    model_names.insert(v.model_id);
  }
  std::map<std::string, int> cls_index, model_index;
  for (const auto& c : class_names) {
    cls_index[c] = static_cast<int>(out.classes.size());
    out.classes.push_back({c, 0.f, 0, 0, 0.f});
  }
  for (const auto& m : model_names) {
    model_index[m] = static_cast<int>(out.models.size());
    out.models.push_back(m);
  }

  // Model width: catalog extents when given, else the widest view's point extents.
  std::vector<float> model_width(out.models.size(), 0.f), model_height(out.models.size(), 0.f);
  std::vector<int> model_class(out.models.size(), -1);
  int dim = -1;
  std::vector<float> rows;
  size_t skipped = 0, no_origin = 0;
  for (const auto& v : views) {
    const int m = model_index[v.model_id];
    const int c = cls_index[v.cls];
    if (model_class[m] >= 0 && model_class[m] != c)
      throw StageError("model '" + v.model_id + "' appears with two classes: " +
                       out.classes[model_class[m]].name + " and " + v.cls);
    model_class[m] = c;
    float w = std::max(v.object_size.x(), v.object_size.y());
    float h = v.object_size.z();
    if ((!(w > 0.f) || !(h > 0.f)) && !v.scan.points.empty()) {
      Eigen::AlignedBox3f box;
      for (const auto& p : v.scan.points) box.extend(p);
      if (!(w > 0.f)) w = std::max(box.sizes().x(), box.sizes().y());
      if (!(h > 0.f)) h = box.max().z();  // catalog models stand on z = 0
    }
    if (std::isfinite(w)) model_width[m] = std::max(model_width[m], w);
    if (std::isfinite(h)) model_height[m] = std::max(model_height[m], h);

    // Viewing frame: x = horizontal direction from the sensor to the object. A simulator that
    // circles a fixed model returns every view in the model frame, where d would be the same
    // vector in all 16 views; turning it into the viewing frame gives each word the rotated
    // copies the paper got by turning the object in front of a fixed sensor (Sect. VII).
    Eigen::Matrix3f to_view = Eigen::Matrix3f::Identity();
    if (v.scan.origin && v.scan.origin->allFinite()) {
      const Eigen::Vector3f look = v.object_centroid - *v.scan.origin;
      if (look.head<2>().norm() > 1e-3f)
        to_view = Eigen::AngleAxisf(-std::atan2(look.y(), look.x()), Eigen::Vector3f::UnitZ()).toRotationMatrix();
    } else {
      ++no_origin;
    }
    const auto& F = v.features.values;
    if (static_cast<size_t>(F.rows()) != v.segmentation.parts.size())
      throw StageError("training view " + std::to_string(v.view) + " of model '" + v.model_id +
                       "' has " + std::to_string(F.rows()) + " feature rows for " +
                       std::to_string(v.segmentation.parts.size()) + " parts");
    if (F.rows() == 0) continue;
    if (dim < 0) {
      dim = static_cast<int>(F.cols());
      out.feature_names = v.features.names;
    } else if (F.cols() != dim) {
      throw StageError("training view " + std::to_string(v.view) + " of model '" + v.model_id +
                       "' has " + std::to_string(F.cols()) + " feature columns, earlier views " +
                       std::to_string(dim));
    }
    for (Eigen::Index i = 0; i < F.rows(); ++i) {
      if (!F.row(i).allFinite() || !v.segmentation.parts[i].centroid.allFinite()) {
        ++skipped;
        continue;
      }
      for (Eigen::Index j = 0; j < F.cols(); ++j) rows.push_back(F(i, j));
      out.d.push_back(to_view * (v.object_centroid - v.segmentation.parts[i].centroid));
      out.height.push_back(v.scan.HeightAboveGround(v.scan.pose * v.segmentation.parts[i].centroid));
      out.cls.push_back(c);
      out.model.push_back(m);
      out.view.push_back(v.view);
      ++out.classes[c].parts;
    }
  }
  if (out.d.empty()) throw StageError("the training views contain no parts with finite features");
  if (skipped) spdlog::warn("voter training: skipped {} parts with non-finite features", skipped);
  if (no_origin)
    spdlog::warn("voter training: {} of {} views have no sensor origin; their shape vectors stay "
                 "in the scan frame", no_origin, views.size());
  out.features = Eigen::Map<RowMatrixXf>(rows.data(), static_cast<Eigen::Index>(out.d.size()), dim);

  for (size_t c = 0; c < out.classes.size(); ++c) {
    std::vector<float> widths;
    for (size_t m = 0; m < out.models.size(); ++m)
      if (model_class[m] == static_cast<int>(c) && model_width[m] > 0.f) widths.push_back(model_width[m]);
    out.classes[c].models = static_cast<int>(
        std::count(model_class.begin(), model_class.end(), static_cast<int>(c)));
    out.classes[c].width = Median(widths);
    for (size_t m = 0; m < out.models.size(); ++m)
      if (model_class[m] == static_cast<int>(c)) out.classes[c].height = std::max(out.classes[c].height, model_height[m]);
    if (!(out.classes[c].width > 0.f))
      throw StageError("class '" + out.classes[c].name +
                       "': no model has a known size (TrainingView::object_size is zero and the "
                       "views have no points)");
  }
  return out;
}

}  // namespace furnihost::voting
