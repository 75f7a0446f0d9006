"""The explanation pages' blocks, which reproduce the measured figures, run as tests/docs/test_docs.py runs
every other page's (in a file of their own, so that two test workers share the pages' time)."""
from __future__ import annotations

import pytest

from test_docs import MEASUREMENT_PAGES, ROOT, ran_commands, run_page


@pytest.mark.parametrize("page", MEASUREMENT_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_block_of_the_explanation_page_runs(page, tmp_path, tmp_path_factory, record_property):
    run_page(page, tmp_path, ran_commands(tmp_path_factory), record_property)
