#pragma once
// Multi-body system model of a machine tool (patent CN104200063, in general form): bodies
// B0 (bed) ... Bn joined in a tree; each joint j with lower body L(j) has the characteristic
// matrix T_L(j),j = T_p * dT_p * T_s(q) * dT_s(q): ideal static position, static errors
// (position, squareness), ideal motion along or about its axis, motion errors. The forming
// point seen in the workpiece frame is P_w = [T_0,w]^-1 T_0,t P_t, with the products taken
// along the workpiece and tool branches; the spatial error is E = P_w,ideal - P_w.
//
// Units: positions mm, translational errors um, rotational errors urad, E in um.
// Pure numerics, thread-safe (const).

#include <Eigen/Dense>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace mtcal::processing {

enum class JointType { kFixed, kPrismatic, kRevolute };

/// Component of a small rigid-body error: translations along x, y, z (um), rotations about
/// x, y, z (urad), in the frame of the joint.
enum class ErrorComponent { kDx = 0, kDy, kDz, kRx, kRy, kRz };

struct Joint {
  std::string body;
  std::string parent;
  JointType type = JointType::kFixed;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();      ///< unit direction (prismatic) or rotation axis
  std::string coordinate;                               ///< machine coordinate driving it ("x", "c", ...)
  Eigen::Vector3d offset_mm = Eigen::Vector3d::Zero();  ///< ideal static position in the parent frame
};

/// One error parameter: an ISO 230-1 name, where it acts and whether it varies with motion.
struct ErrorTerm {
  std::string name;    ///< EXX, EBX, EC0Y, ...
  int joint = 0;       ///< index into joints()
  bool motion = true;  ///< true: a function of the joint coordinate (in dT_s); false: constant (in dT_p)
  ErrorComponent component = ErrorComponent::kDx;
};

class MultibodyModel {
 public:
  /// @throws InputError when the tree is not a tree rooted at the bed, a body is unknown,
  ///         an error name repeats, or an axis is not a unit vector.
  MultibodyModel(std::string name, std::vector<Joint> joints, std::vector<ErrorTerm> terms, std::string tool_body,
                 std::string workpiece_body, Eigen::Vector3d tool_point_mm, std::string bed_body = "bed");

  /// Reads a machine description (config/machines/*.json). @throws InputError naming key and why
  static MultibodyModel fromJson(const nlohmann::json& j, const std::string& source);

  const std::string& name() const { return name_; }
  const std::vector<Joint>& joints() const { return joints_; }
  const std::vector<ErrorTerm>& terms() const { return terms_; }
  /// The machine coordinates in the order the coordinate vectors use.
  const std::vector<std::string>& coordinates() const { return coordinates_; }
  /// Index of an error term by name. @throws InputError when unknown
  int termIndex(const std::string& name) const;
  /// Lower-order body array: L^r(body) as a body name ("bed" once r reaches the root).
  std::string lowerBody(const std::string& body, int r) const;

  /// Forming point in the workpiece frame, ideal (no error), mm.
  Eigen::Vector3d idealPoint(const Eigen::VectorXd& q) const;
  /// Forming point with the given error values (one per term, um / urad), full product, mm.
  Eigen::Vector3d actualPoint(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const {
    return actualPoint(q, errors, tool_point_mm_);
  }
  /// Any point fixed to the tool body (`point_mm` in the tool frame, e.g. a reflector mounted
  /// off the tool point), seen in the workpiece frame, mm.
  Eigen::Vector3d actualPoint(const Eigen::VectorXd& q, const Eigen::VectorXd& errors,
                              const Eigen::Vector3d& point_mm) const;
  /// E = P_ideal - P by the full homogeneous-transform product, um.
  Eigen::Vector3d spatialErrorUm(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const;
  /// dE/d(error) at zero error: 3 x terms(), um per um (translations) or per urad (rotations).
  /// Its rows are the equivalent error equations (the patent's eqs. 36-38) at q.
  Eigen::Matrix3Xd jacobian(const Eigen::VectorXd& q) const { return jacobian(q, tool_point_mm_); }
  /// The same for a point fixed to the tool body at `point_mm` in the tool frame.
  Eigen::Matrix3Xd jacobian(const Eigen::VectorXd& q, const Eigen::Vector3d& point_mm) const;
  /// Rotation of the tool body relative to the workpiece, actual against ideal, as a small
  /// rotation vector about the workpiece's X, Y, Z (urad): what angular optics read.
  /// Full product: R_actual R_ideal^T = exp([theta]x).
  Eigen::Vector3d orientationErrorUrad(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const;
  /// d(orientationErrorUrad)/d(error) at zero error: 3 x terms(), urad per um or urad.
  Eigen::Matrix3Xd orientationJacobian(const Eigen::VectorXd& q) const;
  /// The characteristic matrix T_p dT_p T_s(coordinate) dT_s of one joint (coordinate in mm
  /// or degrees, errors as 6-vectors dx dy dz (um) rx ry rz (urad)).
  Eigen::Matrix4d jointMatrix(int joint, double coordinate, const Eigen::Matrix<double, 6, 1>& static_error,
                              const Eigen::Matrix<double, 6, 1>& motion_error) const;
  /// Joints of the tool and workpiece branches, from the bed outwards.
  const std::vector<int>& toolJoints() const { return tool_.joints; }
  const std::vector<int>& workpieceJoints() const { return workpiece_.joints; }
  /// Index in coordinates() of the coordinate driving a joint, -1 for a fixed joint.
  int coordinateOfJoint(int joint) const;
  const Eigen::Vector3d& toolPoint() const { return tool_point_mm_; }

  /// First-order spatial error jacobian(q) * errors, um.
  Eigen::Vector3d spatialErrorLinearUm(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const {
    return jacobian(q) * errors;
  }

 private:
  struct Branch {
    std::vector<int> joints;  ///< from the bed outwards
  };
  Branch branchTo(const std::string& body) const;
  void checkSizes(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const;
  /// Pose of the tool frame in the workpiece frame, W^-1 T, full product.
  Eigen::Matrix4d relativePose(const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const;
  /// The ideal relative pose at q and its derivative with respect to each error term (at zero).
  struct PoseDerivatives {
    Eigen::Matrix4d pose;
    std::vector<Eigen::Matrix4d> d_pose;
  };
  PoseDerivatives poseDerivatives(const Eigen::VectorXd& q) const;
  /// The four factors of a joint at q with its static and motion error 6-vectors (um/urad).
  void factors(int joint, const Eigen::VectorXd& q, const Eigen::Matrix<double, 6, 1>& static_error,
               const Eigen::Matrix<double, 6, 1>& motion_error, Eigen::Matrix4d out[4]) const;
  Eigen::Matrix4d chain(const Branch& branch, const Eigen::VectorXd& q, const Eigen::VectorXd& errors) const;
  int coordinateIndex(const Joint& joint) const;

  std::string name_;
  std::vector<Joint> joints_;
  std::vector<ErrorTerm> terms_;
  std::vector<std::string> coordinates_;
  std::string bed_;
  Branch tool_, workpiece_;
  Eigen::Vector3d tool_point_mm_;
};

}  // namespace mtcal::processing
