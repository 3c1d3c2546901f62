"""The exception phenomena raises for a scene it cannot use."""

from typing import List, NamedTuple


class Problem(NamedTuple):
    """One problem in a scene: where it is (file, 1-based line and column; 0 when the
    scene has no place for it) and what is wrong."""

    file: str
    line: int
    column: int
    message: str

    def __str__(self) -> str:
        if self.line:
            return f"{self.file}:{self.line}:{self.column}: {self.message}"
        return self.message


class SceneError(ValueError):
    """A scene that cannot be read, validated or built: ``problems`` lists each problem
    with its file, line and column, as the ``phenomena`` command reports them."""

    def __init__(self, message: str, problems=()):
        super().__init__(message)
        self.problems: List[Problem] = [Problem(*p) for p in problems]
