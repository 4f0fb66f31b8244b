"""One run of a configuration, from start-up to results (used by the command line).
"""
