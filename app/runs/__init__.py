"""Training runs and experiments: creation, checkpoint artefacts, the comparison of the
Human and Agent Preference Trees, verdicts and reports, and their REST API and pages.
"""
