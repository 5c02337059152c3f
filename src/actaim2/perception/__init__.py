"""Perception: PointCloud2 decoding, static extrinsics, fusion, robot self-filter, orthographic views.

Everything here is ROS-free; the `actaim2_perception` ROS package only converts messages and
calls these modules, so training-data preprocessing and the running node share one code path.
"""
