"""The people layer (issue 26): members of a collection (a study's participants, a
survey's respondents), the one lookup of their invite tokens, and recruiting through open
links, written once for both kinds of collection.
"""
