"""The kernel's base: components, domains, graphs and networks, expressions read from text, structural
decisions, argument checks, switching times, bounded symbolic work.  Imports nothing above it.
"""
