"""Fourier representations: the FFT backend, sparse Fourier signals, integration (thesis ch. 4)."""
