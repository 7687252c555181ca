"""Small DSP kernels shared by the models."""
