"""What every actaim2 node package shares; node packages depend on it and never on each other.

  main           node entry points: spin a server, spin until done, run a client body
  params         one parameter table per node, declared by one helper; shipped YAML checked against it
  keypose        actaim2_msgs/Keypose <-> actaim2.keypose.Keypose
  pointcloud2    sensor_msgs/PointCloud2 <-> actaim2.perception.cloud_codec
  transforms     TF messages <-> 4x4 matrices, /tf_static publisher and listener
  action_client  an ActionClient safe to use from several threads
  stamps         Time and Duration messages <-> nanoseconds and seconds, whole seconds carried
"""
