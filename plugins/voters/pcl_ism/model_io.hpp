// voters.pcl_ism, private to the plugin: PCL's ISM model as text (PCL writes and reads it only
// through files) and the values its text format would not keep (model_io.cpp).
#pragma once

#include <pcl/features/normal_3d.h>
#include <pcl/point_types.h>
#include <pcl/recognition/implicit_shape_model.h>

#include <cstddef>
#include <memory>
#include <string>

namespace furnihost::voters {

using IsmModel = pcl::features::ISMModel;

// The model as PCL's text (never copies it: PCL 1.13's ISMModel copy is unsafe).
std::string ModelToText(IsmModel& model);

// A model read from PCL's text.
std::shared_ptr<IsmModel> ModelFromText(const std::string& text);

// Zeroes what would not survive PCL's text format (NaN, inf); returns how many values changed.
size_t Sanitize(IsmModel& m);

}  // namespace furnihost::voters
