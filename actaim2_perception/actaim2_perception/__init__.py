"""Point-cloud fusion, robot self-filter, orthographic views and the calibration publisher of actaim2. Thin ROS adapters over the `actaim2` library."""
