"""The tick against recorded closed loops of the code before it was made faster.

Closed loops of the LBR Table 4.1 stacks, the iiwa bench stack switched to collision
avoidance and the iCub Table 3.7 stack (a stack switch at tick 150 in each, see
``tick_recording.py``), with the C kernels and with their numpy reference: q_v, qdot_v and
the tank energies equal the recording of the same kernels to 1e-12.
"""

import numpy as np
import pytest
from tick_recording import DATA, RUNS, platform, run

from ifc_spg import kernels


@pytest.mark.parametrize('impl', ['native', 'numpy'])
@pytest.mark.parametrize('name', sorted(RUNS))
def test_closed_loop_equals_the_recording(name, impl):
    if impl == 'native' and kernels.native is None:
        pytest.skip('the C kernels are not built')
    data = np.load(DATA)
    if str(data['platform']) != platform():
        pytest.skip(f"recorded on {data['platform']}, this is {platform()}: round-off differs "
                    '(tick_recording.py says how to record here)')
    recorded = data[f'{name}-{impl}']
    log = run(name, kernels.native if impl == 'native' else kernels.reference)
    np.testing.assert_allclose(log, recorded, rtol=0, atol=1e-12)
