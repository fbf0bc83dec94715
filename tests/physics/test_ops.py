"""small_matmul: eager and compiled branches against ``@``."""

import pytest
import torch

from torchrl_auv.physics._ops import small_matmul

SHAPES = [
    ((5,), (5, 3)),
    ((4, 5), (5, 3)),
    ((2, 4, 5), (5, 3)),
    ((2, 4, 5), (2, 5, 3)),
    ((2, 3, 4, 5), (3, 5, 1)),
    ((6, 6), (2, 6, 6)),
]


@pytest.mark.parametrize(("a_shape", "b_shape"), SHAPES)
def test_both_branches_equal_matmul(a_shape, b_shape):
    gen = torch.Generator().manual_seed(0)
    a = torch.randn(a_shape, generator=gen, dtype=torch.float64)
    b = torch.randn(b_shape, generator=gen, dtype=torch.float64)
    expected = a @ b
    torch.testing.assert_close(small_matmul(a, b), expected, rtol=0, atol=0)
    traced = torch.compile(small_matmul, backend="eager", fullgraph=True)(a, b)
    torch.testing.assert_close(traced, expected, rtol=1e-12, atol=1e-12)
