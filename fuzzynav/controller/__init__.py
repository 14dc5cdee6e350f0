"""The paper's static navigation: a Mamdani fuzzy controller defined by plain data (Table 1, the listing), its
fast evaluator and a scikit-fuzzy reference to check it against."""
