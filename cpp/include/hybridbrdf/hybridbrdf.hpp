// hybridbrdf — umbrella header: everything the library offers.
#pragma once

#include "hybridbrdf/analytic.hpp"
#include "hybridbrdf/baselines.hpp"
#include "hybridbrdf/batch.hpp"
#include "hybridbrdf/fresnel.hpp"
#include "hybridbrdf/ggx.hpp"
#include "hybridbrdf/math.hpp"
#include "hybridbrdf/model.hpp"
#include "hybridbrdf/params.hpp"
#include "hybridbrdf/sampling.hpp"
#include "hybridbrdf/svbrdf.hpp"
#include "hybridbrdf/version.hpp"
#include "hybridbrdf/warp.hpp"
