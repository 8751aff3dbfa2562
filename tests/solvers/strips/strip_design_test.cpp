#include <gtest/gtest.h>
#include "strips/strip_design.h"
namespace parafab { namespace {
TEST(StripDesign, Placeholder) { SUCCEED(); }
}}
