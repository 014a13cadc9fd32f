"""drake-continuum: object classification and recognition by continuum-arm wraps, on Drake."""

__version__ = "0.1.0"
