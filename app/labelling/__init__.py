"""Labelling: a participant's bracket, next match and labels (the hot path), the consistency
check, disagreement pairs, and the participant's REST API and pages.
"""
