# Copyright 2026 The gyro_tdc Authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Sphinx configuration of the gyro_tdc documentation site.

Two builds read this file:

* ``make docs``: ``sphinx-build -W --keep-going -b html doc build/docs/html``.
* ``rosdoc2 build --package-path .`` (how the ROS documentation index builds a package):
  rosdoc2 copies ``doc/`` into its ``wrapped_sphinx_directory``, writes its own ``conf.py``
  there that executes this one, then adds autodoc, intersphinx (inventories of the packages
  it built before, no download), the Read the Docs theme and myst_parser. It also writes
  pages of its own beside ours (``sphinx-apidoc`` output, a copy of ``doc/`` as
  ``user_docs/``, the standard documents); our pages document the same objects, so those are
  excluded below, where they would be duplicates or pages outside every toctree.

The reference pages under ``reference/`` are generated from the code at build time by the
extensions in ``_ext/`` (parameter tables, topics, argparse help, autodoc).
"""

import os
import re
import sys

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, '_ext'))

#: True when rosdoc2 runs this file from the copy of doc/ it builds.
in_rosdoc2 = os.path.basename(here) == 'wrapped_sphinx_directory'

# The package documented is the one beside this doc/, installed or not (the editable install
# of `make venv` may point at another tree). Under rosdoc2 this file runs from rosdoc2's
# conf.py, as exec(open("<package>/doc/conf.py").read()): that path names the package.
root = os.path.dirname(here)
if in_rosdoc2:
    with open(__file__, encoding='utf-8') as wrapper:
        run = re.search(r'exec\(open\("(.+?)"\)', wrapper.read())
    if run:
        root = os.path.dirname(os.path.dirname(run.group(1)))
if os.path.isfile(os.path.join(root, 'gyro_tdc', '__init__.py')):
    sys.path.insert(0, root)

# -- Project --------------------------------------------------------------------------------

project = 'gyro_tdc'
author = 'The gyro_tdc Authors'
copyright = '2026, The gyro_tdc Authors. Apache-2.0'
release = '0.1.0'
version = '0.1'

# -- General --------------------------------------------------------------------------------

extensions = [
    'sphinx.ext.autodoc',
    'sphinx.ext.napoleon',
    'sphinx.ext.mathjax',
    'myst_parser',
    'sphinx_rtd_theme',
    'gyro_tdc_nodes',
    'gyro_tdc_cli',
    'gyro_tdc_api',
]

root_doc = 'index'
source_suffix = {'.rst': 'restructuredtext', '.md': 'markdown'}
exclude_patterns = ['_build', '_ext', 'Thumbs.db', '.DS_Store']
templates_path = []

# reST roles without a domain (`x`) are code, as in the docstrings.
default_role = 'code'

# MyST: the Markdown pages may use ::: fences, $math$, definition lists and heading anchors.
myst_enable_extensions = ['colon_fence', 'deflist', 'dollarmath']
myst_heading_anchors = 3

# -- Autodoc and napoleon (numpydoc docstrings) ---------------------------------------------

autodoc_member_order = 'bysource'
autodoc_typehints = 'signature'
autodoc_preserve_defaults = True
autodoc_default_options = {}
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True
napoleon_preprocess_types = True

# -- HTML -----------------------------------------------------------------------------------

html_theme = 'sphinx_rtd_theme'
html_theme_options = {'navigation_depth': 3, 'collapse_navigation': False}
# Wrapping reference tables (doc/_ext/static/gyro_tdc.css).
html_static_path = ['_ext/static']
html_css_files = ['gyro_tdc.css']
html_show_sourcelink = False

# -- rosdoc2 --------------------------------------------------------------------------------

# No network where the docs are built: no intersphinx mapping of our own (rosdoc2 adds the
# local inventories of the packages it built before, which needs none).
rosdoc2_settings = {
    'enable_autodoc': True,
    'enable_intersphinx': True,
    'override_theme': True,
    'support_markdown': True,
}

if in_rosdoc2:
    exclude_patterns += [
        'user_docs', 'user_docs.rst', 'user_docs_*.rst',     # a second copy of doc/
        'gyro_tdc.rst', 'gyro_tdc.*.rst', 'modules.rst',     # sphinx-apidoc: reference/api
        'standards.rst', 'standard_docs', '__readme_include.rst',
        'sphinx_output',                                     # rosdoc2's output directory
    ]

#: The package-root documents rosdoc2 copies into ``standard_docs/original/`` (its names).
STANDARD_DOCUMENTS = ('CHANGELOG.rst', 'CONTRIBUTING.md', 'LICENSE', 'README.md')


def _root_includes(app, docname, source):
    """
    Point ``include:: ../X`` of a page at rosdoc2's copy of the package-root document X.

    doc/changelog.rst includes ../CHANGELOG.rst (the changelog stays at the package root,
    where catkin and bloom look for it); in rosdoc2's copy of doc/ that path leads nowhere,
    but rosdoc2 has copied the file into standard_docs/original/.
    """
    if '/' in docname:
        return
    for name in STANDARD_DOCUMENTS:
        source[0] = source[0].replace(f'.. include:: ../{name}',
                                      f'.. include:: standard_docs/original/{name}')


def setup(app):
    """Connect the rosdoc2 shim (only when rosdoc2 builds)."""
    if in_rosdoc2:
        app.connect('source-read', _root_includes)
