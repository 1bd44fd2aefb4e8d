"""Studies: creation and preparation (sample, seed, render), candidates, trees and label
exports, crowd options and label quality, and their REST API and pages.
"""
