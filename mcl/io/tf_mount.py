"""The lidar's mount on the car from a bag's ``/tf_static`` transforms (``tf2_msgs/TFMessage``).

`static_mount()` walks the chain of child-in-parent transforms from the scan's frame up to
``base_link`` and composes them in the plane: the lidar's forward offset (metres along base_link's
x axis), its yaw (radians) and whether it is mounted upside down (its beam angles then turn the
other way in base_link).
"""

from __future__ import annotations

import math

__all__ = ["BASE_FRAME", "static_mount", "yaw_of"]

BASE_FRAME = "base_link"


def yaw_of(q) -> float:
    """Yaw (radians) of a quaternion message (x, y, z, w)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def static_mount(tf_messages: list, scan_frame: str, warnings: list[str]):
    """(x offset m, yaw rad, mirrored) of the scan frame in base_link from /tf_static messages,
    or None. ``mirrored``: the scan frame is upside down (its z axis points down, a lidar mounted
    on its head), so its beam angles turn the other way in base_link."""
    edges: dict[str, tuple[str, float, float, float, bool]] = {}
    for msg in tf_messages:
        for tf in msg.transforms:
            tr, q = tf.transform.translation, tf.transform.rotation
            down = 1.0 - 2.0 * (q.x * q.x + q.y * q.y) < 0.0  # R[2, 2]: where z points
            edges[tf.child_frame_id.lstrip("/")] = (
                tf.header.frame_id.lstrip("/"),
                tr.x,
                tr.y,
                yaw_of(q),
                down,
            )
    # Walk from the scan frame up to base_link, composing child-in-parent transforms.
    frame, x, y, yaw, flip = scan_frame.lstrip("/"), 0.0, 0.0, 0.0, False
    for _ in range(len(edges) + 1):
        if frame == BASE_FRAME:
            if abs(y) > 0.01:
                warnings.append(
                    f"the lidar sits {y:+.3f} m to the side of {BASE_FRAME}; only its forward "
                    "offset is modelled"
                )
            return x, yaw, flip
        if frame not in edges:
            return None
        parent, px, py, pyaw, pdown = edges[frame]
        if pdown:  # the child's y axis and angles are mirrored in the parent's plane
            y, yaw = -y, -yaw
        c, s = math.cos(pyaw), math.sin(pyaw)
        x, y, yaw, flip = px + c * x - s * y, py + s * x + c * y, pyaw + yaw, flip != pdown
        frame = parent
    return None
