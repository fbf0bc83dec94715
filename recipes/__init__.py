"""Training and evaluation recipes in the TorchRL sota-implementations shape.

Run them from the repository root as ``python -m recipes.<name>``.
"""
