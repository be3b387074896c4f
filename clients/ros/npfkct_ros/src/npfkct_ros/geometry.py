"""Rigid transforms on geometry_msgs types, without numpy or tf.transformations (which Debian 12's
ROS does not ship): quaternions as (x, y, z, w) tuples."""

import math


def yaw_of(q):
    """Yaw (rotation about z) of a quaternion with fields x, y, z, w."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def quat_from_rpy(roll, pitch, yaw):
    """(x, y, z, w) of the rotation R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


def quat_mul(a, b):
    """The quaternion product a * b (apply b, then a)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def quat_conj(q):
    """The inverse of a unit quaternion."""
    return (-q[0], -q[1], -q[2], q[3])


def rotate(q, v):
    """The vector v rotated by the unit quaternion q."""
    x, y, z, _ = quat_mul(quat_mul(q, (v[0], v[1], v[2], 0.0)), quat_conj(q))
    return (x, y, z)


class Rigid:
    """A rigid transform p' = R p + t (maps points of the child frame into the parent frame)."""

    def __init__(self, t=(0.0, 0.0, 0.0), q=(0.0, 0.0, 0.0, 1.0)):
        self.t = tuple(t)
        self.q = tuple(q)

    @classmethod
    def of_transform(cls, transform):
        """From a geometry_msgs/Transform."""
        tr, ro = transform.translation, transform.rotation
        return cls((tr.x, tr.y, tr.z), (ro.x, ro.y, ro.z, ro.w))

    @classmethod
    def of_pose(cls, pose):
        """From a geometry_msgs/Pose."""
        p, o = pose.position, pose.orientation
        return cls((p.x, p.y, p.z), (o.x, o.y, o.z, o.w))

    def __mul__(self, other):
        """self after other: (self * other)(p) = self(other(p))."""
        r = rotate(self.q, other.t)
        return Rigid((r[0] + self.t[0], r[1] + self.t[1], r[2] + self.t[2]),
                     quat_mul(self.q, other.q))

    def inverse(self):
        """The inverse transform."""
        qi = quat_conj(self.q)
        r = rotate(qi, self.t)
        return Rigid((-r[0], -r[1], -r[2]), qi)

    def to_transform(self, transform):
        """Writes into a geometry_msgs/Transform; returns it."""
        (transform.translation.x, transform.translation.y, transform.translation.z) = self.t
        (transform.rotation.x, transform.rotation.y, transform.rotation.z,
         transform.rotation.w) = self.q
        return transform

    def to_pose(self, pose):
        """Writes into a geometry_msgs/Pose; returns it."""
        pose.position.x, pose.position.y, pose.position.z = self.t
        (pose.orientation.x, pose.orientation.y, pose.orientation.z,
         pose.orientation.w) = self.q
        return pose

    def yaw(self):
        """Yaw of the rotation (about the parent's z)."""
        x, y, z, w = self.q
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
