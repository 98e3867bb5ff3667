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
  path_check    the stress-path watchdog's rules, re-applied to a results file's series
  calibrate     `triaxial calibrate`: micro-parameters fitted to macroscopic targets
  replay        `replay-critical`: the app's critical-state stop replayed on a test's series
  campaign_table `campaign-table`: one row per test of a campaign (end, critical point, band)
  plots         the figures (matplotlib, imported when drawing)

Every command: `python3 -m sandcell_analysis COMMAND ...` (__main__.py), with the package installed
(`pip install --no-build-isolation --no-deps apps/analysis`) or PYTHONPATH=apps/analysis.

From Python, with the package installed, or apps/analysis (source tree) or <prefix>/share/sandcell
(installed by cmake) on sys.path:

    from sandcell_analysis import results, critical
    test, why = results.read_test("run/p-b0.00-p0_500kPa.h5")
    verdict = critical.detect_critical(test["eps_q"], test)  # version 3: the window in eps_q
"""
