"""Time stepping: the compiled sampled-data engine, its scipy reference, and results."""
