"""Discrete-time controllers: one compiled function per law, one config class per family."""
