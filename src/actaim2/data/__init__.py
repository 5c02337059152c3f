"""Self-supervised data collection (paper appendix "Dataset Generation", Algorithm 1).

Modules, one job each (docs/data.md tells the whole story):
  trajectory        in-memory records: keyposes, multi-camera RGB-D observations, object state
  actions           the four-keypose action primitive every sampler returns; the Sampler protocol
  object_cloud      object points from the cameras (fusion, support and face removal, DBSCAN parts)
  gripper           the robot preset's open hand (boxes) against a cloud: collisions, what lies between the fingers
  random_sampler    random sampling (appendix "1. Random Sampling")
  grasp             pluggable grasp proposers; the geometric antipodal one
  grasp_sampler     heuristic grasp sampling (appendix "2. Heuristic Grasping Sampling")
  gmm_sampler       GMM-adaptive sampling (appendix "3. GMM-based Adaptive Sampling")
  vgg               VGG-19 `features` stack that loads a user's torchvision weight file
  encoder           the image encoder E over camera pictures, and the default autoencoder
  encoder_training  self-supervised training of the default encoder
  part_motion       how the moved parts moved between the robot-hidden O_init and O_final (depth, rigid fits)
  success           the success model over a part's motion, threshold calibration, labelling metrics
  labelling         measures motions and embeds a stored dataset, calibrates, writes visual labels
  storage           the on-disk dataset (tar chunks of PNG/JSON members + index.jsonl)
  splits            the catalogue's splits by instance and category, leak check
  torch_dataset     PyTorch Datasets: (O_i, a_i, z) keyframes and (O_init, z) pairs
  collect           the collection loop: worker processes, resume, progress
  stats             success per category and sampler, outcome diversity, size, speed
  collect_cli       `actaim2 collect`
  stats_cli         `actaim2 stats`
"""
