"""UKF applications (:class:`kfgen.sim.ukf.app.UkfApplication`): the chapter's nanosatellite
attitude filter and a small range-bearing tracker."""
