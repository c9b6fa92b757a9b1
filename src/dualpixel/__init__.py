"""dualpixel: dual-pixel defocus deblurring.

Implements Abuolaim, Delbracio, Kelly, Brown and Milanfar, "Learning to Reduce Defocus Blur by
Realistically Modeling Dual-Pixel Data", ICCV 2021: DP data synthesis (``dualpixel.optics``,
``dualpixel.synthesis``), deblurring networks and calibration.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
