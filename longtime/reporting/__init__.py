"""What a person reads: the terminal report, the results page, figures, compare, history, the paper's numbers."""
