"""
Speed against accuracy, as suites.

The trade-off charts (``tradeoff``, ``tradeoff_report``, ``analysis``), where the method fails
(``failure``), the automatic plan's promise on random and built-in scenes (``promise``,
``auto_scenes``), the README's headline figures (``headline``), the filter's response
(``response``).
"""
