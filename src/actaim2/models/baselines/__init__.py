"""Baseline mode selectors of the paper's evaluation (ActAIM's CVAE, VQ-VAE), same interface as the CGMVAE."""
