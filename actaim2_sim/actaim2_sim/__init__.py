"""SAPIEN simulation node and the episode runner (sim loop) of actaim2. Thin ROS adapters over the `actaim2` library."""
