"""Print the "Coming from Dakota" keyword tables (docs/tutorials/from_dakota.md), generated
from the deck translator's own lists: ``python scripts/dakota_keywords.py``."""

from rotoruq.study.deck import keyword_table

if __name__ == "__main__":
    print(keyword_table())
