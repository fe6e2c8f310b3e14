"""Analysis and control of tensegrity structures (issue 4)."""
