"""Diffusion Policy: a 1-D conv U-Net noise network, DDPM training, DDIM sampling when acting."""
