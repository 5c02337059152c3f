"""Self-supervised data collection (paper appendix "Dataset Generation", Algorithm 1).

Modules, one job each:
  trajectory      in-memory records: keyposes, multi-camera RGB-D observations, trajectories
  storage         the on-disk dataset (tar chunks of PNG/JSON members + index.jsonl)
  splits          seen / unseen-instance / held-out-category splits (never by trajectory)
  torch_dataset   PyTorch Datasets over a stored dataset
  stats           success per category and sampler, outcome diversity (`actaim2 stats`)
  vgg             VGG-19 `features` stack that loads a user's torchvision weight file
  encoder         the image encoder E over camera views, and the project's self-trained default
  success         task embedding z = E(O_init) - E(O_final), score, threshold calibration
  object_cloud    object points from the cameras (crop, support-plane removal), no robot, no state
  gripper         parallel-gripper volume for geometric collision filtering
  random_sampler  random action sequences (appendix "Random Sampling")
  grasp           pluggable grasp proposers; the geometric antipodal one
  grasp_sampler   heuristic grasp sampling (appendix "Heuristic Grasping Sampling")
  gmm_sampler     GMM-adaptive sampling (appendix "GMM-based Adaptive Sampling")
  collect         the collection loop: worker processes, resume, progress (`actaim2 collect`)
"""
