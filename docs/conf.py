"""Sphinx configuration: MyST Markdown pages, and a reference generated from the code.

``make docs`` builds it with warnings as errors (``-W --keep-going -n``); rosdoc2 builds
it on docs.ros.org through ``rosdoc2.yaml``.
"""
import os
import sys

DOCS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(DOCS, '_ext'))
sys.path.insert(0, os.path.dirname(DOCS))  # the package, when it is not installed (rosdoc2)

project = 'rigid_body_sim'
author = 'rigid_body_sim developers'
copyright = '2025, rigid_body_sim developers'

extensions = ['myst_parser', 'node_reference']
source_suffix = {'.md': 'markdown'}
root_doc = 'index'
# docs/bench/targets.md and summary.md are written by the bench and included by benchmarks.md
exclude_patterns = ['_build', 'bench/targets.md', 'bench/summary.md', 'README.md']
# "## Heading" gets the anchor #heading, for links such as [x](physics.md#integrators)
myst_heading_anchors = 3
myst_enable_extensions = ['dollarmath']
nitpicky = True
html_theme = 'alabaster'
html_title = 'rigid_body_sim'
