"""The .RAY language of both dialects (COMP 575 and its parent, MIT 6.837): text in, the
immutable :class:`~raymitsuba.model.Scene` out, and back. Standard library only: no Mitsuba.

=================  ============================================================
module             what it owns
=================  ============================================================
``lexer``          lines, forbidden characters, tokens with spans, comments
``commands``       the one table of commands per dialect: operands, token
                   positions, the parameter key each feeds (``ParamKey``)
``parser``         the entry points and the choice of dialect
``builder``        the scene state and the commands both dialects share
``comp575``        the COMP 575 reader
``mit6837``        the MIT 6.837 reader
``textures``       texture files: which image format a file holds
``geometry``       the parser's vector and matrix helpers (transform stack)
``diagnostics``    ``FILE:LINE:COLUMN`` messages, "did you mean"
``summary``        what ``raymitsuba check`` prints
``convert``        a MIT 6.837 scene written as COMP 575 text
``writeback``      parameter keys in the text: values written back in place
=================  ============================================================

The meaning of every command is decided in docs/format.md (the contracts) and carried out
here only; later stages read the model.
"""

from raymitsuba.format.parser import (DIALECT_CHOICES, detect_dialect, parse, parse_file,
                                      parse_text)

__all__ = ["DIALECT_CHOICES", "detect_dialect", "parse", "parse_file", "parse_text"]
