"""calibration_publisher: a calibration YAML (hand-eye result) -> latched /tf_static.

Real rigs calibrate their cameras offline; publishing the result on /tf_static (reliable,
transient local) lets every node - and every recorded bag - carry the extrinsics exactly as the
simulator's do, so the fusion node needs no file of its own. YAML format: see
``actaim2.perception.calibration``.
"""
from __future__ import annotations

from rclpy.node import Node

from actaim2.perception.calibration import load_calibration
from actaim2_ros.main import spin
from actaim2_ros.params import declare_parameters
from actaim2_ros.transforms import StaticTransformPublisher, matrix_to_transform

PARAMETERS = {"calibration_file": ("", "YAML: parent_frame + transforms (child frame -> 4x4)")}


class CalibrationPublisher(Node):
    def __init__(self) -> None:
        super().__init__("calibration_publisher")
        path = declare_parameters(self, PARAMETERS)["calibration_file"]
        if not path:
            raise ValueError("parameter 'calibration_file' is empty: give the calibration YAML to publish")
        parent, transforms = load_calibration(path)
        stamp = self.get_clock().now().to_msg()
        self._publisher = StaticTransformPublisher(self)
        self._publisher.send([matrix_to_transform(T, parent, child, stamp) for child, T in transforms.items()])
        self.get_logger().info(f"published {len(transforms)} static transform(s) from {path}: {parent} -> {sorted(transforms)}")


def main(args: list[str] | None = None) -> int:
    return spin(CalibrationPublisher, "calibration_publisher", args)


if __name__ == "__main__":
    raise SystemExit(main())
