#include "mtcal/processing/multibody.h"

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

constexpr double kMmPerUm = 1e-3;
constexpr double kRadPerUrad = 1e-6;

Eigen::Matrix4d translation(const Eigen::Vector3d& t) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 1>(0, 3) = t;
  return m;
}

Eigen::Matrix4d rotation(const Eigen::Vector3d& axis, double angle_rad) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 3>(0, 0) = Eigen::AngleAxisd(angle_rad, axis).toRotationMatrix();
  return m;
}

// Small rigid-body error as an exact transform: translation, then R = Rz Ry Rx.
Eigen::Matrix4d errorTransform(const Eigen::Matrix<double, 6, 1>& v) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 3>(0, 0) = (Eigen::AngleAxisd(v(5) * kRadPerUrad, Eigen::Vector3d::UnitZ()) *
                         Eigen::AngleAxisd(v(4) * kRadPerUrad, Eigen::Vector3d::UnitY()) *
                         Eigen::AngleAxisd(v(3) * kRadPerUrad, Eigen::Vector3d::UnitX()))
                            .toRotationMatrix();
  m.block<3, 1>(0, 3) = v.head<3>() * kMmPerUm;
  return m;
}

// d(errorTransform)/d(component) at zero error, per um or urad.
Eigen::Matrix4d generator(ErrorComponent c) {
  Eigen::Matrix4d g = Eigen::Matrix4d::Zero();
  switch (c) {
    case ErrorComponent::kDx:
      g(0, 3) = kMmPerUm;
      break;
    case ErrorComponent::kDy:
      g(1, 3) = kMmPerUm;
      break;
    case ErrorComponent::kDz:
      g(2, 3) = kMmPerUm;
      break;
    case ErrorComponent::kRx:
      g(2, 1) = kRadPerUrad;
      g(1, 2) = -kRadPerUrad;
      break;
    case ErrorComponent::kRy:
      g(0, 2) = kRadPerUrad;
      g(2, 0) = -kRadPerUrad;
      break;
    case ErrorComponent::kRz:
      g(1, 0) = kRadPerUrad;
      g(0, 1) = -kRadPerUrad;
      break;
  }
  return g;
}

[[noreturn]] void bad(const std::string& source, const std::string& key, const std::string& why) {
  throw InputError(source + ": " + key + ": " + why);
}

Eigen::Vector3d vector3(const nlohmann::json& j, const std::string& source, const std::string& key) {
  if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number()) {
    bad(source, key, "must be an array of 3 numbers");
  }
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

ErrorComponent component(const std::string& text, const std::string& source, const std::string& key) {
  static const std::map<std::string, ErrorComponent> kNames = {
      {"dx", ErrorComponent::kDx}, {"dy", ErrorComponent::kDy}, {"dz", ErrorComponent::kDz},
      {"rx", ErrorComponent::kRx}, {"ry", ErrorComponent::kRy}, {"rz", ErrorComponent::kRz}};
  auto it = kNames.find(text);
  if (it == kNames.end()) bad(source, key, "'" + text + "' is not one of dx, dy, dz, rx, ry, rz");
  return it->second;
}

}  // namespace

MultibodyModel::MultibodyModel(std::string name, std::vector<Joint> joints, std::vector<ErrorTerm> terms,
                               std::string tool_body, std::string workpiece_body, Eigen::Vector3d tool_point_mm,
                               std::string bed_body)
    : name_(std::move(name)),
      joints_(std::move(joints)),
      terms_(std::move(terms)),
      bed_(std::move(bed_body)),
      tool_point_mm_(std::move(tool_point_mm)) {
  std::set<std::string> bodies{bed_};
  for (const auto& j : joints_) {
    if (!bodies.insert(j.body).second) throw InputError("machine '" + name_ + "': body '" + j.body + "' appears twice");
  }
  for (const auto& j : joints_) {
    if (!bodies.count(j.parent)) {
      throw InputError("machine '" + name_ + "': body '" + j.body + "' hangs on unknown body '" + j.parent + "'");
    }
    if (j.type != JointType::kFixed) {
      if (std::abs(j.axis.norm() - 1.0) > 1e-9) {
        throw InputError("machine '" + name_ + "': the axis of '" + j.body + "' is not a unit vector");
      }
      if (j.coordinate.empty())
        throw InputError("machine '" + name_ + "': moving body '" + j.body + "' has no coordinate");
      if (std::find(coordinates_.begin(), coordinates_.end(), j.coordinate) == coordinates_.end()) {
        coordinates_.push_back(j.coordinate);
      }
    }
  }
  std::set<std::string> names;
  for (const auto& t : terms_) {
    if (t.joint < 0 || t.joint >= static_cast<int>(joints_.size())) {
      throw InputError("machine '" + name_ + "': error " + t.name + " refers to no joint");
    }
    if (!names.insert(t.name).second) throw InputError("machine '" + name_ + "': error " + t.name + " appears twice");
  }
  tool_ = branchTo(tool_body);
  workpiece_ = branchTo(workpiece_body);
}

MultibodyModel::Branch MultibodyModel::branchTo(const std::string& body) const {
  Branch branch;
  std::string current = body;
  std::set<std::string> seen;
  while (current != bed_) {
    if (!seen.insert(current).second) throw InputError("machine '" + name_ + "': the bodies form a loop at " + current);
    auto it = std::find_if(joints_.begin(), joints_.end(), [&](const Joint& j) { return j.body == current; });
    if (it == joints_.end()) throw InputError("machine '" + name_ + "': unknown body '" + current + "'");
    branch.joints.insert(branch.joints.begin(), static_cast<int>(it - joints_.begin()));
    current = it->parent;
  }
  return branch;
}

std::string MultibodyModel::lowerBody(const std::string& body, int r) const {
  std::string current = body;
  for (int i = 0; i < r && current != bed_; ++i) {
    auto it = std::find_if(joints_.begin(), joints_.end(), [&](const Joint& j) { return j.body == current; });
    if (it == joints_.end()) throw InputError("machine '" + name_ + "': unknown body '" + current + "'");
    current = it->parent;
  }
  return current;
}

int MultibodyModel::termIndex(const std::string& name) const {
  for (std::size_t i = 0; i < terms_.size(); ++i) {
    if (terms_[i].name == name) return static_cast<int>(i);
  }
  throw InputError("machine '" + name_ + "' has no error term " + name);
}

int MultibodyModel::coordinateIndex(const Joint& joint) const {
  return static_cast<int>(std::find(coordinates_.begin(), coordinates_.end(), joint.coordinate) - coordinates_.begin());
}

void MultibodyModel::factors(int joint, const Eigen::VectorXd& q, const Eigen::Matrix<double, 6, 1>& static_error,
                             const Eigen::Matrix<double, 6, 1>& motion_error, Eigen::Matrix4d out[4]) const {
  const Joint& j = joints_[static_cast<std::size_t>(joint)];
  out[0] = translation(j.offset_mm);
  out[1] = errorTransform(static_error);
  switch (j.type) {
    case JointType::kFixed:
      out[2] = Eigen::Matrix4d::Identity();
      break;
    case JointType::kPrismatic:
      out[2] = translation(j.axis * q(coordinateIndex(j)));
      break;
    case JointType::kRevolute:
      out[2] = rotation(j.axis, q(coordinateIndex(j)) * M_PI / 180.0);
      break;
  }
  out[3] = errorTransform(motion_error);
}

Eigen::Matrix4d MultibodyModel::jointMatrix(int joint, double coordinate,
                                            const Eigen::Matrix<double, 6, 1>& static_error,
                                            const Eigen::Matrix<double, 6, 1>& motion_error) const {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(coordinates_.size()));
  const int c = coordinateOfJoint(joint);
  if (c >= 0) q(c) = coordinate;
  Eigen::Matrix4d f[4];
  factors(joint, q, static_error, motion_error, f);
  return f[0] * f[1] * f[2] * f[3];
}

int MultibodyModel::coordinateOfJoint(int joint) const {
  const Joint& j = joints_[static_cast<std::size_t>(joint)];
  return j.type == JointType::kFixed ? -1 : coordinateIndex(j);
}

Eigen::Matrix4d MultibodyModel::chain(const Branch& branch, const Eigen::VectorXd& q,
                                      const Eigen::VectorXd& errors) const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (int joint : branch.joints) {
    Eigen::Matrix<double, 6, 1> se = Eigen::Matrix<double, 6, 1>::Zero(), me = se;
    for (std::size_t t = 0; t < terms_.size(); ++t) {
      if (terms_[t].joint != joint) continue;
      (terms_[t].motion ? me : se)(static_cast<int>(terms_[t].component)) += errors(static_cast<Eigen::Index>(t));
    }
    Eigen::Matrix4d f[4];
    factors(joint, q, se, me, f);
    m = m * f[0] * f[1] * f[2] * f[3];
  }
  return m;
}

void MultibodyModel::checkSizes(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const {
  if (q.size() != static_cast<Eigen::Index>(coordinates_.size()) ||
      errors.size() != static_cast<Eigen::Index>(terms_.size())) {
    throw InputError("machine '" + name_ + "': expected " + std::to_string(coordinates_.size()) + " coordinates and " +
                     std::to_string(terms_.size()) + " error values");
  }
}

Eigen::Matrix4d MultibodyModel::relativePose(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const {
  checkSizes(q, errors);
  return chain(workpiece_, q, errors).inverse() * chain(tool_, q, errors);
}

Eigen::Vector3d MultibodyModel::actualPoint(const Eigen::VectorXd& q, const Eigen::VectorXd& errors,
                                            const Eigen::Vector3d& point_mm) const {
  return (relativePose(q, errors) * point_mm.homogeneous()).head<3>();
}

namespace {
/// The rotation vector of a rotation matrix close to identity (first order in its skew part).
Eigen::Vector3d smallRotation(const Eigen::Matrix3d& r) {
  return 0.5 * Eigen::Vector3d(r(2, 1) - r(1, 2), r(0, 2) - r(2, 0), r(1, 0) - r(0, 1));
}
}  // namespace

Eigen::Vector3d MultibodyModel::orientationErrorUrad(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const {
  const Eigen::Matrix3d actual = relativePose(q, errors).topLeftCorner<3, 3>();
  const Eigen::Matrix3d ideal = relativePose(q, Eigen::VectorXd::Zero(errors.size())).topLeftCorner<3, 3>();
  const Eigen::AngleAxisd delta(actual * ideal.transpose());
  return delta.axis() * delta.angle() / kRadPerUrad;
}

Eigen::Vector3d MultibodyModel::idealPoint(const Eigen::VectorXd& q) const {
  return actualPoint(q, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(terms_.size())));
}

Eigen::Vector3d MultibodyModel::spatialErrorUm(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const {
  return (idealPoint(q) - actualPoint(q, errors)) * 1000.0;
}

MultibodyModel::PoseDerivatives MultibodyModel::poseDerivatives(const Eigen::VectorXd& q) const {
  const Eigen::Matrix<double, 6, 1> zero = Eigen::Matrix<double, 6, 1>::Zero();
  // The factors of a branch at zero error, and the prefix products before each factor.
  struct Expanded {
    std::vector<Eigen::Matrix4d> factors, prefix;  // prefix[i] = factors[0] ... factors[i-1]
    Eigen::Matrix4d total;
  };
  auto expand = [&](const Branch& branch) {
    Expanded e;
    for (int joint : branch.joints) {
      Eigen::Matrix4d f[4];
      factors(joint, q, zero, zero, f);
      e.factors.insert(e.factors.end(), f, f + 4);
    }
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (const auto& f : e.factors) {
      e.prefix.push_back(m);
      m = m * f;
    }
    e.total = m;
    return e;
  };
  const Expanded tool = expand(tool_);
  const Expanded work = expand(workpiece_);
  PoseDerivatives out;
  const Eigen::Matrix4d w_inv = work.total.inverse();
  out.pose = w_inv * tool.total;
  // d(prefix * dT * suffix) = prefix * G * suffix, suffix = prefix^-1 * total.
  auto derivative = [](const Expanded& e, std::size_t factor, const Eigen::Matrix4d& g) -> Eigen::Matrix4d {
    const Eigen::Matrix4d through = e.prefix[factor] * e.factors[factor];
    return e.prefix[factor] * g * through.inverse() * e.total;
  };
  // pose = W^-1 T: d(pose) = W^-1 dT - W^-1 dW W^-1 T.
  for (const ErrorTerm& term : terms_) {
    const Eigen::Matrix4d g = generator(term.component);
    const std::size_t slot = term.motion ? 3 : 1;
    Eigen::Matrix4d d = Eigen::Matrix4d::Zero();
    for (std::size_t k = 0; k < tool_.joints.size(); ++k) {
      if (tool_.joints[k] == term.joint) d += w_inv * derivative(tool, 4 * k + slot, g);
    }
    for (std::size_t k = 0; k < workpiece_.joints.size(); ++k) {
      if (workpiece_.joints[k] == term.joint) d -= w_inv * derivative(work, 4 * k + slot, g) * out.pose;
    }
    out.d_pose.push_back(d);
  }
  return out;
}

Eigen::Matrix3Xd MultibodyModel::jacobian(const Eigen::VectorXd& q, const Eigen::Vector3d& point_mm) const {
  const PoseDerivatives pd = poseDerivatives(q);
  const Eigen::Vector4d p = point_mm.homogeneous();
  Eigen::Matrix3Xd jac(3, static_cast<Eigen::Index>(terms_.size()));
  for (std::size_t t = 0; t < terms_.size(); ++t) {
    jac.col(static_cast<Eigen::Index>(t)) = -(pd.d_pose[t] * p).head<3>() / kMmPerUm;  // E = P_ideal - P, in um
  }
  return jac;
}

Eigen::Matrix3Xd MultibodyModel::orientationJacobian(const Eigen::VectorXd& q) const {
  const PoseDerivatives pd = poseDerivatives(q);
  const Eigen::Matrix3d ideal_t = pd.pose.topLeftCorner<3, 3>().transpose();
  Eigen::Matrix3Xd jac(3, static_cast<Eigen::Index>(terms_.size()));
  for (std::size_t t = 0; t < terms_.size(); ++t) {
    jac.col(static_cast<Eigen::Index>(t)) = smallRotation(pd.d_pose[t].topLeftCorner<3, 3>() * ideal_t) / kRadPerUrad;
  }
  return jac;
}

MultibodyModel MultibodyModel::fromJson(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object()) throw InputError(source + ": a machine description must be a JSON object");
  for (const char* key : {"name", "joints", "tool", "workpiece"}) {
    if (!j.contains(key)) bad(source, key, "missing");
  }
  std::vector<Joint> joints;
  std::vector<ErrorTerm> terms;
  const auto& list = j["joints"];
  if (!list.is_array()) bad(source, "joints", "must be an array");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const auto& e = list[i];
    const std::string path = "joints[" + std::to_string(i) + "]";
    if (!e.contains("body") || !e.contains("parent")) bad(source, path, "needs body and parent");
    Joint joint;
    joint.body = e["body"].get<std::string>();
    joint.parent = e["parent"].get<std::string>();
    const std::string type = e.value("type", "fixed");
    if (type == "fixed") {
      joint.type = JointType::kFixed;
    } else if (type == "prismatic") {
      joint.type = JointType::kPrismatic;
    } else if (type == "revolute") {
      joint.type = JointType::kRevolute;
    } else {
      bad(source, path + ".type", "'" + type + "' is not fixed, prismatic or revolute");
    }
    if (e.contains("axis")) joint.axis = vector3(e["axis"], source, path + ".axis");
    if (e.contains("offset_mm")) joint.offset_mm = vector3(e["offset_mm"], source, path + ".offset_mm");
    joint.coordinate = e.value("coordinate", "");
    for (const auto& [key, motion] : {std::pair{"motion_errors", true}, std::pair{"static_errors", false}}) {
      if (!e.contains(key)) continue;
      for (const auto& [name, comp] : e[key].items()) {
        if (!comp.is_string()) bad(source, path + "." + key + "." + name, "must be one of dx, dy, dz, rx, ry, rz");
        terms.push_back({name, static_cast<int>(i), motion,
                         component(comp.get<std::string>(), source, path + "." + key + "." + name)});
      }
    }
    joints.push_back(joint);
  }
  const Eigen::Vector3d tool_point =
      j.contains("tool_point_mm") ? vector3(j["tool_point_mm"], source, "tool_point_mm") : Eigen::Vector3d::Zero();
  try {
    return MultibodyModel(j["name"].get<std::string>(), std::move(joints), std::move(terms),
                          j["tool"].get<std::string>(), j["workpiece"].get<std::string>(), tool_point,
                          j.value("bed", "bed"));
  } catch (const InputError& e) {
    throw InputError(source + ": " + e.what());
  }
}

}  // namespace mtcal::processing
