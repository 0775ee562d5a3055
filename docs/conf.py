"""Sphinx configuration of the pendulum_sim documentation (MyST Markdown, autodoc)."""
from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / '_ext'))

project = 'pendulum_sim'
author = 'pendulum_sim developers'
copyright = '2026, pendulum_sim developers'

extensions = [
    'myst_parser',
    'sphinx.ext.autodoc',
    'sphinx.ext.napoleon',
    'reftables',
]

source_suffix = {'.md': 'markdown'}
root_doc = 'index'
exclude_patterns = ['_build', '**/_generated', 'Thumbs.db', '.DS_Store']

myst_enable_extensions = ['colon_fence', 'dollarmath', 'deflist']
myst_heading_anchors = 3

# Broken references are errors (make docs passes -n -W) for every fully qualified name of this
# package, as the pages write them. Names outside it (the standard library, numpy, rclpy: no
# inventory is fetched offline) and the short names docstrings use are not checked.
nitpicky = True
nitpick_ignore_regex = [(r'py:.*', r'(?!pendulum_sim\.).*'),
                        (r'py:.*', r'pendulum_sim\..*\.(_\w+|[A-Z])')]  # private, TypeVar
suppress_warnings = ['ref.python']  # a short name that several classes define as an attribute

autodoc_default_options = {'members': True, 'undoc-members': False, 'show-inheritance': True}
autodoc_typehints = 'description'
autodoc_member_order = 'bysource'
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_ivar = True  # Attributes sections as fields: dataclass fields are members too

html_theme = 'alabaster'
html_static_path = ['_static']
html_title = 'pendulum_sim'
