"""Retargeting: clips of one humanoid skeleton onto another by canonical bone roles
(:mod:`.roles`), with rest-pose alignment and leg-length-scaled root motion (:mod:`.retarget`);
``mimicbench datagen retarget`` (:mod:`.command`)."""
