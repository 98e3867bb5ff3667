"""sandcell_analysis: the analysis of sandcell triaxial results (`triaxial analyze|study|localization`
and the plot after each run).

Modules
  results       the one reader of results files (<test>.h5), index.csv and samples.csv
  critical      the critical-state test (the Python twin of apps/triaxial/protocol/critical.cpp)
  csl           the critical state line e_c = e_Gamma - lambda (p/p_a)^xi and its fit
  m_theta       Lode-angle dependence M(theta) = M_c g(theta), b and theta of a stress state
  dilatancy     dilatancy series, the Li & Dafalias forms and their fits
  fitting       least-squares helpers shared by the fits
  reference     the study's published numbers and the verdict criteria
  analyze       `triaxial analyze`: the pipeline, report.md and summary.json
  study         `triaxial study`: the speed-accuracy and sample-size studies
  localization  `triaxial localization`: local strain fields and the band profile
  plots         the figures (matplotlib, imported when drawing)

From Python, with apps/analysis (source tree) or <prefix>/share/sandcell (installed) on sys.path:

    from sandcell_analysis import results, critical
    test, why = results.read_test("run/p-b0.00-p0_500kPa.h5")
    verdict = critical.detect_critical(test["eps1"], test)
"""
