"""Test-side /cmd_vel listener: a rospy node printing each geometry_msgs/Twist it receives.

Runs under the system Python with Debian's rospy and genpy. Prints ``READY`` once its
subscriber is registered, then one line per message: ``TWIST linear.x angular.z``.
"""

from __future__ import annotations

import sys

import genpy.dynamic
import rospy

TWIST_TEXT = (
    "Vector3 linear\nVector3 angular\n" + "\n" + "=" * 80 + "\n"
    "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
)


def main() -> None:
    twist_type = "geometry_msgs/Twist"
    twist_cls = genpy.dynamic.generate_dynamic(twist_type, TWIST_TEXT)[twist_type]

    def on_twist(msg: object) -> None:
        print(f"TWIST {msg.linear.x} {msg.angular.z}", flush=True)  # type: ignore[attr-defined]

    rospy.init_node("cmd_vel_listener", disable_signals=True)
    rospy.Subscriber("/cmd_vel", twist_cls, on_twist, queue_size=100)
    print("READY", flush=True)
    sys.stdin.read()  # until the test closes stdin
    rospy.signal_shutdown("quit")


if __name__ == "__main__":
    main()
