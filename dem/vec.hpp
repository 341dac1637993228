#pragma once
// Vector type of the DEM library. All quantities are SI (m, kg, s, N, J, Pa).
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products

namespace millflow::dem {

using Vec3 = Eigen::Vector3d;

}  // namespace millflow::dem
