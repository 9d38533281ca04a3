"""Analytic controllers of the papers, each built from an env's nominal model."""
