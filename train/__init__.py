"""Encoders, latent loss, windowing and the trainer."""
