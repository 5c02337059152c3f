"""The learned policy's networks and their geometry (paper: P(a | O, eps) and P(eps | O)).

  predictor       ActionPredictor: multi-view transformer, P(a | O, eps)
  view_geometry   cube placement, cube <-> view pixels, heatmap targets, coarse-to-fine 3-D decode
  rotation_bins   quaternion (x, y, z, w) <-> 72 bins per Euler angle
  augment         RVT scene augmentation: one SE(3) perturbation of views and keypose
"""
