"""Launching node graphs without the ROS `launch` package: one node list (graph.py) makes both
the XML launch files of a real ROS 2 install and what `actaim2 launch` (cli.py) starts."""
