"""The level buffer's lines say how much the sampler knows of each level: a count it has not got is not 0."""

from __future__ import annotations

from fieldgen.run.favoured import BufferLevel


def line(episodes: float) -> str:
    return BufferLevel(seed=3, level=1, points=2, kickoff=(0.1, 0.3), share=0.25, episodes=episodes,
                       success=(0.4, 0.5)).text(levels=8)


def test_a_level_with_no_episode_counted_says_its_success_is_the_prior():
    assert line(0.0) == ("seed 3, level 2: 2 points at kick-off 0.10-0.30, 25% of new episodes, no episode "
                         "counted yet, success 0.40-0.50 (the prior)")


def test_fractional_counts_keep_a_decimal_and_large_ones_their_thousands():
    assert "0.4 episodes counted, success 0.40-0.50" in line(0.4)
    assert "1,234 episodes counted" in line(1234.2)
