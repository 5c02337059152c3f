"""The policy artifact: what training writes and serving, evaluation and fine-tuning read.

  checkpoint  safetensors weights + JSON description, saved and loaded without unpickling
  device      the torch device a policy runs on
  serving     ServingConfig, the defaults /sample_mode and /predict_keypose are served with

It sits below training, serving (``actaim2.policy``) and evaluation, so none of them imports
another to reach a checkpoint.
"""
