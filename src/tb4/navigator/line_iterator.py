"""LineIterator: points along a segment at a fixed step, Nav2 Simple Commander's API.

Steps along x (y for vertical lines), like upstream, so iteration matches scripts written for it; the
collision checker samples by the longer axis itself so steep lines miss no cells.
"""

from __future__ import annotations

import math

__all__ = ["LineIterator"]


def _number(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"{name} must be a number (int or float)")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return value


class LineIterator:
    def __init__(self, x0: float, y0: float, x1: float, y1: float, step_size: float = 1.0) -> None:
        self.x0_ = _number(x0, "x0")
        self.y0_ = _number(y0, "y0")
        self.x1_ = _number(x1, "x1")
        self.y1_ = _number(y1, "y1")
        self.step_size_ = _number(step_size, "step_size")
        if step_size <= 0:
            raise ValueError("step_size must be a positive number")
        if x0 == x1 and y0 == y1:
            raise ValueError("Line has zero length (All 4 points have same coordinates)")
        self.x_ = x0
        self.y_ = y0
        self.valid_ = True
        self.m_ = (y1 - y0) / (x1 - x0) if x1 != x0 else math.inf
        self.b_ = y1 - self.m_ * x1 if x1 != x0 else math.nan

    def isValid(self) -> bool:
        return self.valid_

    def advance(self) -> None:
        """Move one step towards the end point; past the end the iterator becomes invalid."""
        if self.x1_ != self.x0_:
            direction = 1.0 if self.x1_ > self.x0_ else -1.0
            if (self.x1_ - self.x_) * direction > 0:
                lo, hi = sorted((self.x0_, self.x1_))
                self.x_ = round(self.clamp(self.x_ + direction * self.step_size_, lo, hi), 5)
                self.y_ = round(self.m_ * self.x_ + self.b_, 5)
            else:
                self.valid_ = False
        else:
            direction = 1.0 if self.y1_ > self.y0_ else -1.0
            if (self.y1_ - self.y_) * direction > 0:
                lo, hi = sorted((self.y0_, self.y1_))
                self.y_ = round(self.clamp(self.y_ + direction * self.step_size_, lo, hi), 5)
            else:
                self.valid_ = False

    def getX(self) -> float:
        return self.x_

    def getY(self) -> float:
        return self.y_

    def getX0(self) -> float:
        return self.x0_

    def getY0(self) -> float:
        return self.y0_

    def getX1(self) -> float:
        return self.x1_

    def getY1(self) -> float:
        return self.y1_

    def get_line_length(self) -> float:
        """Length of the segment (a float; upstream returned a complex number)."""
        return math.hypot(self.x1_ - self.x0_, self.y1_ - self.y0_)

    @staticmethod
    def clamp(n: float, min_n: float, max_n: float) -> float:
        return min(max(n, min_n), max_n)
