"""Mode selector and action predictor services, bag recorder and player of actaim2. Thin ROS adapters over the `actaim2` library."""
