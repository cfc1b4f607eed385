"""Analysis of exported study responses: tables in, statistics and figures out.

This package never imports Django; it works on the response table that
``studyapp.results.export`` writes (see :mod:`analysis.tables`):

    from analysis.study import AnalysisConfig, analyse
    from analysis.report import write_report

    result = analyse(table, AnalysisConfig(bootstrap=1000))
    write_report(result, "out/")  # report.html, summary.json, tables, figures
"""

from analysis.tables import AnalysisError

__all__ = ["AnalysisError"]
