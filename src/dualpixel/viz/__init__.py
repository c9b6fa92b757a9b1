"""Figures: what a picture says better than numbers."""
