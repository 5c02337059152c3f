"""Training of the learned policy: losses, configs, the training loop (paper: training procedure)."""
