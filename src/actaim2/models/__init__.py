"""The learned policy's networks and their geometry (paper: P(a | O, eps) and P(eps | O)).

  predictor       ActionPredictor: multi-view transformer, P(a | O, eps)
  view_geometry   cube placement, cube <-> view pixels, heatmap targets, coarse-to-fine 3-D decode
  rotation_bins   quaternion (x, y, z, w) <-> 72 bins per Euler angle
  augment         RVT scene augmentation: one SE(3) perturbation of views and keypose
  selector        the CGMVAE mode selector, P(eps | O_init): q(c | x, y, O) by Bayes' rule
  selector_base   what every selector shares (config, condition encoder, z scaling, samples)
  baselines/      CVAE (ActAIM) and VQ-VAE (VQVAE-RVT) selectors with the same interface
  obs_encoder     the condition O: robot-hidden views -> one token per view (CNN, or user VGG-19)
  eps_decoder     p(eps | x, O): a small transformer over per-view tokens
  resmlp          residual MLP heads (mu_c, Sigma_c, q_x, q_y)
  gumbel          Gumbel-max draws of the cluster c
  registry        a selector built from its configuration (checkpoints store only that)
"""
