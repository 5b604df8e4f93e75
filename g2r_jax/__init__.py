"""g2r_jax: computer-graphics images to RAW DNGs of one target camera."""
