#include "coordinator/http/api_tokens.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace tcfarm::http {
namespace {

const std::string kAdmin = "adm1n-0123456789abcdef";
const std::string kReader = "r3ad-0123456789abcdef";
const std::string kSubmitter = "subm1t-0123456789abcdef";
const std::string kFourth = "f0urth-0123456789abcdef";

// The message Parse throws, or "" when it accepts the text.
std::string ParseError(const std::string& text) {
  try {
    ApiTokens::Parse(text, "tokens.txt");
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "";
}

TEST(ApiTokensTest, EveryLineFormNamesItsRoleByTheFieldThatIsARole) {
  const ApiTokens tokens = ApiTokens::Parse("# farm tokens\n\n"
                                            "admin " + kAdmin + "\n" +
                                            kReader + "\tREAD   # the dashboard\r\n"
                                            "submit:" + kSubmitter + "\n" +
                                            kFourth + ":admin\n",
                                            "tokens.txt");
  EXPECT_EQ(tokens.size(), 4u);
  EXPECT_EQ(tokens.Find(kAdmin)->role, Role::kAdmin);
  EXPECT_EQ(tokens.Find(kReader)->role, Role::kRead);
  EXPECT_EQ(tokens.Find(kSubmitter)->role, Role::kSubmit);
  EXPECT_EQ(tokens.Find(kFourth)->role, Role::kAdmin);
  EXPECT_FALSE(tokens.Find("unknown-0123456789abcdef"));
  EXPECT_FALSE(tokens.Find(""));
  EXPECT_FALSE(tokens.Find(kAdmin + "x"));
  EXPECT_FALSE(tokens.Find(kAdmin.substr(1)));
}

TEST(ApiTokensTest, TheTokenIdIsAStablePrefixOfItsHashNotTheToken) {
  const ApiTokens tokens = ApiTokens::Parse("admin " + kAdmin, "t");
  const std::string id = tokens.Find(kAdmin)->tokenId;
  EXPECT_EQ(id.size(), 12u);
  EXPECT_EQ(id, TokenId(kAdmin));
  EXPECT_NE(id, TokenId(kReader));
  EXPECT_EQ(kAdmin.find(id), std::string::npos);
}

TEST(ApiTokensTest, BadLinesNameTheFileAndLineButNeverTheToken) {
  struct Case {
    std::string text;
    std::string expected;
  };
  const Case cases[] = {
      {"admin\n", "tokens.txt line 1: has 1 field(s)"},
      {"\n# c\nadmin " + kAdmin + " extra\n", "tokens.txt line 3: has 3 field(s)"},
      {"owner " + kAdmin + "\n", "tokens.txt line 1: neither field is a role"},
      {"read admin\n", "tokens.txt line 1: both fields name a role"},
      {"admin " + std::string(513, 'a') + "\n", "tokens.txt line 1: the token is 513 characters long; expected at most 512"},
      {"admin " + kAdmin + "\"x\n", "tokens.txt line 1: the token holds a character"},
      {"admin =" + kAdmin + "\n", "tokens.txt line 1: the token holds a character"},
      {"admin " + kAdmin + "\nread " + kAdmin + "\n", "tokens.txt line 2: repeats the token of line 1"},
      {"# nothing here\n\n", "tokens.txt holds no token"},
  };
  for (const Case& c : cases) {
    const std::string message = ParseError(c.text);
    EXPECT_EQ(message.rfind(c.expected, 0), 0u) << message << "\nfor: " << c.text;
    EXPECT_EQ(message.find(kAdmin), std::string::npos) << message;
    EXPECT_EQ(message.find(kAdmin.substr(0, 10)), std::string::npos) << message;
  }
}

// The farm's owner may choose a short token: it is taken, with a warning on stderr.
TEST(ApiTokensTest, AShortTokenIsTakenWithAWarning) {
  const ApiTokens tokens = ApiTokens::Parse("read s3cret\n", "tokens.txt");
  ASSERT_TRUE(tokens.Find("s3cret"));
  EXPECT_EQ(tokens.Find("s3cret")->role, Role::kRead);
}

TEST(ApiTokensTest, PaddedBase64TokensAreAccepted) {
  EXPECT_EQ(ParseError("read abcdefghijklmnop+/==\n"), "");
  EXPECT_NE(ParseError("read abcdefghij=klmnop\n"), "");
}

// The header is taken byte for byte: nothing but the exact token matches, whatever a
// decoding or a C string would have made of the rest.
TEST(ApiTokensTest, OnlyTheExactTokenIsFound) {
  const ApiTokens tokens = ApiTokens::Parse("admin " + kAdmin + "\n", "tokens.txt");
  ASSERT_TRUE(tokens.Find(kAdmin));
  const std::string withNul = kAdmin + std::string(1, '\0') + "junk";
  const std::string percentEncoded = kAdmin.substr(0, 2) + "%" + "6D" + kAdmin.substr(3);  // 'm' is %6D
  ASSERT_EQ(kAdmin[2], 'm');
  for (const std::string& near : {withNul, kAdmin + "%00junk", kAdmin + "junk", kAdmin + "\t",
                                  percentEncoded, kAdmin.substr(0, kAdmin.size() - 1), std::string()}) {
    EXPECT_FALSE(tokens.Find(near)) << near;
  }
}

TEST(BearerTokenTest, TheTokenIsEveryByteAfterTheScheme) {
  EXPECT_EQ(BearerToken("Bearer abc"), "abc");
  EXPECT_EQ(BearerToken("bEARER   abc \t"), "abc");
  EXPECT_EQ(BearerToken("Bearer TOK%45N"), "TOK%45N");
  EXPECT_EQ(BearerToken("Bearer TOKEN%00junk"), "TOKEN%00junk");
  EXPECT_EQ(BearerToken(std::string("Bearer TOKEN\0junk", 17)), std::string("TOKEN\0junk", 10));
  EXPECT_EQ(BearerToken("Bearer a b"), "a b");
  for (const char* none : {"", "Bearer", "Bearer ", "Bearer   ", "Basic abc", "Bearerabc", "Token abc"}) {
    EXPECT_FALSE(BearerToken(none)) << none;
  }
}

TEST(ApiTokensTest, AnUnreadableFileIsNamed) {
  try {
    ApiTokens::Load("/nonexistent/tokens.txt");
    FAIL() << "no error";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()).rfind("/nonexistent/tokens.txt: cannot read it", 0), 0u) << error.what();
  }
}

}  // namespace
}  // namespace tcfarm::http
