"""The analyses on a model: Routhian reduction and steady motion, impulses and impacts, scenes, derived
models.
"""
