"""OdeSystem -> differentiable torch physics block."""
