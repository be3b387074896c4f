#include "npfkct/robot/urdf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <sstream>
#include <string>

namespace npfkct::robot {
namespace {

using object_search::CameraJoint;
using object_search::CameraPoseFor;
using object_search::RobotConfig;
using object_search::Vec3;

// robot/urdf/: Fetch's head chain with the dimensions of its published URDF
// (fetch_description: the torso lift, the head pan and tilt, the camera and its optical frame;
// an arm link off the path), and Stretch's head (a fixed mast, a pan about the vertical and a
// tilt; dimensions after Hello Robot's stretch_description, rounded; no lift on the path).
std::string ReadFile(const std::string& name) {
  std::ifstream in(std::string(NPFKCT_URDF_DIR) + "/" + name);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

const std::string kFetch = ReadFile("fetch_head.urdf");
const std::string kStretch = ReadFile("stretch_head.urdf");

UrdfSelection FetchSelection() {
  UrdfSelection s;
  s.name = "fetch-urdf";
  s.base_link = "base_link";
  s.camera_link = "head_camera_rgb_optical_frame";
  s.optical_frame = true;
  s.lift_joint = "torso_lift_joint";
  s.pan_joint = "head_pan_joint";
  s.tilt_joint = "head_tilt_joint";
  return s;
}

UrdfSelection StretchSelection() {
  UrdfSelection s;
  s.name = "stretch-urdf";
  s.base_link = "base_link";
  s.camera_link = "camera_link";
  s.pan_joint = "joint_head_pan";
  s.tilt_joint = "joint_head_tilt";
  s.footprint_radius = 0.2;
  s.reach = 0.8;
  return s;
}

// The camera pose of Fetch's head chain written out by hand from the URDF's numbers.
Vec3 FetchCameraAt(const RobotConfig& c, Vec3* forward) {
  const double h = c.yaw + c.pan;
  // The pan joint's axis in the base frame, then the tilt's offset and the camera's along the
  // turned and pitched head.
  const Vec3 pan_axis(-0.086875 + 0.053125, 0, 0.37743 + c.lift + 0.603001);
  const Vec3 tilt(pan_axis.x() + 0.14253 * std::cos(c.pan), 0.14253 * std::sin(c.pan),
                  pan_axis.z() + 0.057999);
  const Vec3 fwd(std::cos(h) * std::cos(c.tilt), std::sin(h) * std::cos(c.tilt), -std::sin(c.tilt));
  const Vec3 left(-std::sin(h), std::cos(h), 0);
  const Vec3 up = fwd.cross(left);
  const double cy = std::cos(c.yaw), sy = std::sin(c.yaw);
  const Vec3 tilt_world(c.x + cy * tilt.x() - sy * tilt.y(), c.y + sy * tilt.x() + cy * tilt.y(),
                        tilt.z());
  *forward = fwd;
  return tilt_world + 0.055 * fwd + 0.02 * left + 0.0225 * up;
}

TEST(UrdfTest, FetchsHeadChainBecomesItsDescription) {
  auto fetch = DescriptionFromUrdf(kFetch, FetchSelection());
  ASSERT_TRUE(fetch.ok()) << fetch.status().ToString();
  EXPECT_EQ(fetch->name, "fetch-urdf");
  EXPECT_DOUBLE_EQ(fetch->lift_max, 0.386);
  EXPECT_DOUBLE_EQ(fetch->pan_min, -1.57);
  EXPECT_DOUBLE_EQ(fetch->tilt_max, 1.45);
  // Three moving joints, the fixed ones composed into one tail: four joints, not six.
  ASSERT_EQ(fetch->chain.size(), 4u);
  EXPECT_EQ(fetch->chain[0].role, CameraJoint::Role::kLift);
  EXPECT_EQ(fetch->chain[3].type, CameraJoint::Type::kFixed);
  for (const RobotConfig& c :
       {RobotConfig{0, 0, 0, 0, 0, 0}, RobotConfig{1, -2, 0.7, 0.3, 0.4, 0.5},
        RobotConfig{-0.5, 0.25, -2.5, 0.1, -1.2, -0.6}}) {
    Vec3 forward;
    const Vec3 at = FetchCameraAt(c, &forward);
    const auto pose = CameraPoseFor(*fetch, c);
    EXPECT_LT((pose.position - at).norm(), 1e-9)
        << pose.position.transpose() << " / " << at.transpose();
    EXPECT_LT((pose.forward - forward).norm(), 1e-9);
  }
}

TEST(UrdfTest, StretchPlansWithoutALift) {
  auto stretch = DescriptionFromUrdf(kStretch, StretchSelection());
  ASSERT_TRUE(stretch.ok()) << stretch.status().ToString();
  EXPECT_FALSE(stretch->has_lift());
  EXPECT_EQ(stretch->lift_min, 0.0);
  EXPECT_EQ(stretch->lift_max, 0.0);
  const auto low = CameraPoseFor(*stretch, RobotConfig{0, 0, 0, 0, 0, 0});
  const auto lifted = CameraPoseFor(*stretch, RobotConfig{0, 0, 0, 0.3, 0, 0});
  EXPECT_EQ(low.position, lifted.position);  // no joint plays the lift
  EXPECT_NEAR(low.position.z(), 0.028 + 1.22 + 0.04 + 0.03 + 0.02, 1e-9);
  // A positive tilt about +y looks down; a positive pan turns left.
  EXPECT_LT(CameraPoseFor(*stretch, RobotConfig{0, 0, 0, 0, 0, 0.5}).forward.z(), -0.4);
  EXPECT_GT(CameraPoseFor(*stretch, RobotConfig{0, 0, 0, 0, 0.5, 0}).forward.y(), 0.4);
}

TEST(UrdfTest, KinematicsMatchKdlOnAnOddChain) {
  // Joints turned every way (rpy on each origin, a tilted axis, a continuous joint held at 0
  // between them): the description's forward kinematics against KDL's own.
  const char* odd = R"(<robot name="odd">
    <link name="base"/><link name="a"/><link name="b"/><link name="c"/><link name="d"/><link name="cam"/>
    <joint name="lift" type="prismatic"><origin xyz="0.1 0.2 0.5" rpy="0.1 -0.2 0.3"/>
      <parent link="base"/><child link="a"/><axis xyz="0 0.2 1"/><limit lower="-0.1" upper="0.5" effort="1" velocity="1"/></joint>
    <joint name="spin" type="continuous"><origin xyz="0 0 0.1" rpy="0 0.5 0"/>
      <parent link="a"/><child link="b"/><axis xyz="1 0 0"/></joint>
    <joint name="pan" type="revolute"><origin xyz="0.05 0 0.2" rpy="0.3 0 -0.4"/>
      <parent link="b"/><child link="c"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
    <joint name="tilt" type="revolute"><origin xyz="0.02 0.01 0.03" rpy="0 0 0"/>
      <parent link="c"/><child link="d"/><axis xyz="0 1 0.3"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
    <joint name="mount" type="fixed"><origin xyz="0.04 0 0.01" rpy="1.2 0.3 -0.7"/>
      <parent link="d"/><child link="cam"/></joint>
  </robot>)";
  UrdfSelection s;
  s.base_link = "base";
  s.camera_link = "cam";
  s.lift_joint = "lift";
  s.pan_joint = "pan";
  s.tilt_joint = "tilt";
  auto robot = DescriptionFromUrdf(odd, s);
  ASSERT_TRUE(robot.ok()) << robot.status().ToString();
  // KDL, built here from the same numbers, one segment per URDF joint.
  auto frame = [](double x, double y, double z, double r, double p, double w) {
    return KDL::Frame(KDL::Rotation::RPY(r, p, w), KDL::Vector(x, y, z));
  };
  auto moving = [](const char* name, const KDL::Frame& origin, KDL::Vector axis,
                   KDL::Joint::JointType type) {
    axis.Normalize();
    return KDL::Segment(KDL::Joint(name, origin.p, origin.M * axis, type), origin);
  };
  KDL::Chain chain;
  chain.addSegment(
      moving("lift", frame(0.1, 0.2, 0.5, 0.1, -0.2, 0.3), {0, 0.2, 1}, KDL::Joint::TransAxis));
  chain.addSegment(moving("spin", frame(0, 0, 0.1, 0, 0.5, 0), {1, 0, 0}, KDL::Joint::RotAxis));
  chain.addSegment(
      moving("pan", frame(0.05, 0, 0.2, 0.3, 0, -0.4), {0, 0, 1}, KDL::Joint::RotAxis));
  chain.addSegment(
      moving("tilt", frame(0.02, 0.01, 0.03, 0, 0, 0), {0, 1, 0.3}, KDL::Joint::RotAxis));
  chain.addSegment(
      KDL::Segment(KDL::Joint(KDL::Joint::None), frame(0.04, 0, 0.01, 1.2, 0.3, -0.7)));
  KDL::ChainFkSolverPos_recursive fk(chain);
  for (const RobotConfig& c :
       {RobotConfig{0, 0, 0, 0.2, 0.3, -0.4}, RobotConfig{0, 0, 0, -0.1, -1, 1},
        RobotConfig{0, 0, 0, 0.5, 0.9, 0.2}}) {
    KDL::JntArray q(4);
    q(0) = c.lift;
    q(1) = 0.0;
    q(2) = c.pan;
    q(3) = c.tilt;
    KDL::Frame f;
    ASSERT_GE(fk.JntToCart(q, f), 0);
    const auto pose = CameraPoseFor(*robot, c);
    EXPECT_LT((pose.position - Vec3(f.p.x(), f.p.y(), f.p.z())).norm(), 1e-9);
    const KDL::Vector x = f.M.UnitX(), y = f.M.UnitY();
    EXPECT_LT((pose.forward - Vec3(x.x(), x.y(), x.z())).norm(), 1e-9);
    EXPECT_LT((pose.left - Vec3(y.x(), y.y(), y.z())).norm(), 1e-9);
  }
}

TEST(UrdfTest, BadUrdfsAndSelectionsNameTheField) {
  auto field = [](std::string_view xml, const UrdfSelection& s) {
    auto r = DescriptionFromUrdf(xml, s);
    if (r.ok() || r.status().field_violations().empty()) return std::string("ok");
    return r.status().field_violations()[0].field;
  };
  EXPECT_EQ(field("not xml at all", FetchSelection()), "urdf");
  EXPECT_EQ(field("<robot name='x'><link name='a'/><joint/></robot>", FetchSelection()), "urdf");
  EXPECT_EQ(field(std::string(kMaxUrdfBytes + 1, ' '), FetchSelection()), "urdf");
  UrdfSelection s = FetchSelection();
  s.base_link = "nope";
  EXPECT_EQ(field(kFetch, s), "baseLink");
  s = FetchSelection();
  s.camera_link = "shoulder_pan_link";  // a sibling branch: reachable, but via the arm
  s.base_link = "head_pan_link";
  EXPECT_EQ(field(kFetch, s), "cameraLink");
  s = FetchSelection();
  s.camera_link = "missing";
  EXPECT_EQ(field(kFetch, s), "cameraLink");
  s = FetchSelection();
  s.lift_joint = "head_pan_joint";  // revolute
  s.pan_joint = "";
  EXPECT_EQ(field(kFetch, s), "liftJoint");
  s = FetchSelection();
  s.pan_joint = "shoulder_pan_joint";  // off the path to the camera
  EXPECT_EQ(field(kFetch, s), "panJoint");
  s = FetchSelection();
  s.tilt_joint = "torso_lift_joint";  // prismatic, and the lift's too
  EXPECT_EQ(field(kFetch, s), "tiltJoint");
  // Nested 50,000 deep (the parser recursed once per level and overflowed the stack), and
  // nesting hidden in comments, CDATA and attribute values, which does not count.
  std::string deep = "<robot name='r'>";
  for (int i = 0; i < 50000; ++i) deep += "<link name='a'>";
  EXPECT_EQ(field(deep + "</robot>", FetchSelection()), "urdf");
  std::string hidden = kFetch;
  hidden.insert(hidden.find("<link name=\"base_link\"/>"),
                "<!-- " + std::string(100, '<') + "a -->" + "<![CDATA[<a><a><a>]]>");
  EXPECT_EQ(field(hidden, FetchSelection()), "ok");
  std::string floating = kFetch;  // a copy to change
  floating.replace(floating.find("type=\"revolute\""), 15, "type=\"floating\"");
  EXPECT_EQ(field(floating, FetchSelection()), "urdf");
}

TEST(UrdfTest, ALongChainIsRefused) {
  std::string xml = "<robot name='long'><link name='l0'/>";
  for (int i = 1; i <= 40; ++i) {
    xml += "<link name='l" + std::to_string(i) + "'/><joint name='j" + std::to_string(i) +
           "' type='revolute'><parent link='l" + std::to_string(i - 1) + "'/><child link='l" +
           std::to_string(i) +
           "'/><axis xyz='0 0 1'/><limit lower='-1' upper='1' effort='1' velocity='1'/></joint>";
  }
  xml += "</robot>";
  UrdfSelection s;
  s.base_link = "l0";
  s.camera_link = "l40";
  auto r = DescriptionFromUrdf(xml, s);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("more than 16 joints"), std::string::npos)
      << r.status().message();
}

}  // namespace
}  // namespace npfkct::robot
