"""Elo ratings: the standard logistic model, in plain Python (no rating library is among the pinned
dependencies).

A player rated `a` is expected to score E = 1 / (1 + 10 ** ((b - a) / 400)) against one rated `b` (a win
scores 1, a draw 0.5, a loss 0). After a game in which it scored S, it gains K * (S - E) and its opponent
loses as much: every update is zero-sum, so a league's total rating changes only as players join it.

Self-play rates a run's snapshots (agents/selfplay.py) from the matches of its evaluations: a pairing's n
games enter as n updates at the pairing's mean score (`rate_pairing`), so that the order of its games does not
matter and a lopsided pairing moves the two ratings as far as n single games would.
"""

from __future__ import annotations

from typing import Iterable, Mapping

INITIAL = 1000.0  # a player's rating before its first game (a snapshot after the first joins at its
# predecessor's rating: `league_ratings`)
K_FACTOR = 32.0


def expected(a: float, b: float) -> float:
    """The score a player rated `a` expects against one rated `b`."""
    return 1.0 / (1.0 + 10.0 ** ((b - a) / 400.0))


def update(a: float, b: float, score: float, k: float = K_FACTOR) -> tuple[float, float]:
    """The two ratings after one game in which the player rated `a` scored `score` (1 win, 0.5 draw, 0 loss)."""
    if not 0.0 <= score <= 1.0:
        raise ValueError(f"a game's score is 0 (loss), 0.5 (draw) or 1 (win), or a mean of them; got {score}")
    change = k * (score - expected(a, b))
    return a + change, b - change


def score(wins: float, draws: float, losses: float) -> float:
    """The mean score of a pairing's games: wins count 1, draws 1/2."""
    games = wins + draws + losses
    if games <= 0:
        raise ValueError("a pairing of no games has no score")
    return (wins + 0.5 * draws) / games


def rate_pairing(ratings: dict, a, b, wins: float, draws: float, losses: float, k: float = K_FACTOR) -> None:
    """`ratings` (player -> rating) after a pairing in which `a` won, drew and lost that many games against `b`:
    as many updates as games, each at the pairing's mean score; in place."""
    s = score(wins, draws, losses)
    for _ in range(int(round(wins + draws + losses))):
        ratings[a], ratings[b] = update(ratings[a], ratings[b], s, k)


def league_ratings(matches: Iterable[tuple[str, str, Mapping[str, float]]], k: float = K_FACTOR) -> dict[str, float]:
    """Every player's rating after `matches` in order: (player, opponent, {"win", "draw", "loss"}: the player's
    games). A player meets the league at INITIAL, or, the first time it plays as the player of a match against
    players already rated, at the rating of the player rated last (a newer snapshot starts where the one before
    it stands)."""
    ratings: dict[str, float] = {}
    for player, opponent, games in matches:
        for name in (opponent, player):
            if name not in ratings:
                ratings[name] = list(ratings.values())[-1] if ratings and name == player else INITIAL
        rate_pairing(ratings, player, opponent, games["win"], games["draw"], games["loss"], k)
    return ratings
