"""Sim-to-real fine-tuning from teleoperated demonstrations (paper, real-world experiments).

  intrinsics        pinhole intrinsics fitted to an organized cloud, with the residual
  bag_episodes      the demonstrations of a recorded bag: keyposes, cloud sets, labels, verdicts
  bag2dataset       demonstrations -> the training-dataset format of collection (``data/storage``)
  bag2dataset_cli   `actaim2 bag2dataset`
  heldout           held-out demonstrations for validation, stratified by mode label
  clusters          which cluster of the mode selector each labelled demonstration falls into
  finetune          fine-tuning a checkpoint's selector and predictor (the training loop's joint phase)
  finetune_cli      `actaim2 finetune`
"""
