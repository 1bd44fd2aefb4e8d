"""Tree-reading surveys (the paper's user study): questions, stimuli, respondents' screens,
results and statistics, and their REST API and pages.
"""
