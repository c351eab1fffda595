"""Shading: camera rays, pigment patterns, POV-Ray's lighting model, and the Whitted tracer."""
