"""The three thesis pendulums checked independently of their object files: equations coded by hand,
a SymPy derivation from the positions alone, the exact elliptic solution and a long-double
reference."""
