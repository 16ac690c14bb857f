"""The FLS bench cases build their frame (20 regions on 400 x 400) and time it, with and without
structure rejection."""
from __future__ import annotations

import pytest

from sonar_tracking.cli import bench


@pytest.mark.parametrize('name', ['fls.frame_400', 'fls.frame_400_structure'])
def test_fls_frame_cases_make_and_run(name):
    case = bench.cases()[name]
    fn = case.make()          # raises unless the first frame holds the 20 regions
    fn()
